"""Loading an untrusted model file: the static checks, then the toolkit's loader (which dry-runs
the model) under a memory cap. The server's sandbox (league/server/sandbox/child.py, confined
first) and `league check` (league.validation.local) both load models with `load_checked`.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from league import agents
from league.validation import checks


def load_checked(model_path: Path, memory_mb: int | None):
    """The agent of a model file (its kind from its suffix: .onnx, else TorchScript) after the
    static checks; the address space capped at `memory_mb` over the runtime's own (None: no cap)."""
    if model_path.suffix == ".onnx":
        checks.check_onnx(model_path)
        agents.import_onnxruntime().disable_telemetry_events()  # before the cap: its footprint is not the model's
        cap_address_space(memory_mb)
        return agents.load_agent(model_path, name="submission")
    checks.check_torchscript_archive(model_path)
    torch = import_torch()
    cap_address_space(memory_mb)
    module = torch.jit.load(str(model_path), map_location="cpu")  # a GPU's tensors onto the CPU
    agents.onto_cpu(module)  # and its device constants (or refused, naming CUDA and the fix)
    checks.check_torchscript_graph(module)
    return agents.torch_module_agent(module, name="submission")


def import_torch() -> Any:
    """torch, on one thread (set once per process: a sandbox forked from the server has it so)."""
    if "torch" in sys.modules:
        return sys.modules["torch"]
    import warnings

    import torch

    torch.set_num_threads(1)
    torch.set_num_interop_threads(1)
    warnings.simplefilter("ignore", DeprecationWarning)  # torch.jit is in maintenance, still supported
    return torch


def cap_address_space(extra_mb: int | None) -> None:
    """The runtime's own footprint (torch maps ~0.7 GB) plus what the model may allocate. Linux
    only (elsewhere the address space is not capped: macOS does not enforce RLIMIT_AS)."""
    if extra_mb is None or not sys.platform.startswith("linux"):
        return
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (virtual_memory_size() + extra_mb * 1024 * 1024,) * 2)


def virtual_memory_size() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


def failure_reason(error: BaseException, memory_mb: int) -> str:
    """One line for the student (the full message goes to the log, stderr)."""
    print(f"{type(error).__name__}: {error}", file=sys.stderr, flush=True)
    reason = getattr(error, "reason", None) or f"{type(error).__name__}: {' '.join(str(error).split())[:300]}"
    if isinstance(error, MemoryError) or "alloc" in reason.lower():
        return f"out of memory (the cap is {memory_mb} MB): {reason}"
    return reason
