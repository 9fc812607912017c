"""`league check` on a student's machine: the server's validation, run here without the server.

`check_model` runs the model in a child process of its own (`python -m league.validation.local`),
as the server runs it in a sandbox: the same static checks and loader (league.validation.loading,
whose dry run is the toolkit's), the same memory cap over the runtime's own footprint, the same
CPU-time budgets (league.validation.timing: to load, per call with the first-call allowance, per
run) and the same timed dry run. What it does not do is isolate the model (the server's sandbox:
no network, no files, a user of its own): the file is the student's own. A call over its budget
is stopped by the CPU-time limit of the child where the system has one (POSIX), or by a
wall-clock backstop. The verdict, and the reason of a refusal, are the server's for the same
limits.

The child writes its progress and its verdict as JSON lines to a file the parent names; what the
model's runtime prints (its stderr and stdout) is the report's log.
"""
from __future__ import annotations

import importlib.util
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

from league.validation.limits import SandboxLimits
from league.validation.report import ValidationReport
from league.validation.timing import DRY_RUN_CALLS, load_over

WALL_BACKSTOP = 4.0  # a child that stops using the CPU is given up after 4x its CPU budget, + a margin
WALL_MARGIN_S = 10.0
ONE_THREAD = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "ORT_DISABLE_TELEMETRY": "1"}  # inference on one thread, as in the server's sandbox
# How the kernel stops a process over its CPU-time limit (soft: SIGXCPU; past the hard one: SIGKILL)
CPU_STOPS = {-getattr(signal, name) for name in ("SIGXCPU", "SIGKILL") if hasattr(signal, name)}


def check_model(model_file: Path, limits: SandboxLimits) -> ValidationReport:
    """The server's verdict on a model file (its kind from its suffix) for these limits."""
    with tempfile.TemporaryDirectory(prefix="league-check-") as folder:
        progress = Path(folder) / "progress.jsonl"
        command = [sys.executable, "-m", "league.validation.local", str(model_file), str(progress),
                   json.dumps(asdict(limits))]
        child = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, env={**os.environ, **ONE_THREAD})
        timed_out = False
        try:
            log, _ = child.communicate(timeout=wall_backstop(limits))
        except subprocess.TimeoutExpired:
            child.kill()
            log, timed_out = child.communicate()[0], True
        text = log[-limits.log_limit:].decode("utf-8", errors="replace")
        records = [json.loads(line) for line in progress.read_text().splitlines()] if progress.exists() else []
    return verdict(records, None if timed_out else child.returncode, text, limits)


def missing_runtime(kind: str) -> str | None:
    """What to install to check a model of this kind here, if something is missing."""
    from league.agents import INSTALL_ONNX, INSTALL_TORCH

    modules, install = (("onnx", "onnxruntime"), INSTALL_ONNX) if kind == "onnx" else (("torch",), INSTALL_TORCH)
    missing = [module for module in modules if importlib.util.find_spec(module) is None]
    if not missing:
        return None
    return f"checking {kind} models here needs {' and '.join(missing)}: {install}"


def wall_backstop(limits: SandboxLimits) -> float:
    calls = min(limits.run_cpu_s, DRY_RUN_CALLS * 4 * limits.step_deadline_s + limits.first_call_allowance_s)
    return WALL_BACKSTOP * (limits.load_cpu_s + calls) + WALL_MARGIN_S


def verdict(records: list[dict], returncode: int | None, log: str, limits: SandboxLimits) -> ValidationReport:
    """The report the child wrote, or why it ended without one (its last record says where it was;
    `returncode` None: it stopped answering and was killed)."""
    last = records[-1] if records else {"phase": "starting"}
    if last["phase"] == "done":
        return ValidationReport(last["ok"], last["obs_dim"], last["error"], log, last["cpu_ms_per_observation"])
    doing = {"starting": "starting", "loading": "loading", "call": "calling"}[last["phase"]]
    if returncode is None and last["phase"] == "call":
        reason = f"the model stopped answering without using the CPU (no answer after {wall_backstop(limits):g} s)"
    elif returncode is None or returncode in CPU_STOPS:
        reason = last["over"] if last["phase"] == "call" else load_over(limits)
    elif returncode < 0:
        reason = f"the model's process crashed ({signal.Signals(-returncode).name}) while {doing} it; see --log"
    else:
        reason = f"the model's process exited with code {returncode} while {doing} it; see --log"
    return ValidationReport(False, None, reason, log)


# --------------------------------------------------------------------------- the child


def main(model_file: str, progress_file: str, limits_json: str) -> int:
    from league.agents import plain_text
    from league.validation.loading import failure_reason

    limits = SandboxLimits(**json.loads(limits_json))
    with open(progress_file, "a") as progress:
        def say(**record) -> None:
            progress.write(json.dumps(record) + "\n")
            progress.flush()

        try:
            report = timed_validation(Path(model_file), limits, say)
        except Exception as error:  # the model's failure is the verdict, in the sandbox's words
            report = refused(plain_text(failure_reason(error, limits.memory_mb)))
        say(phase="done", **report)
    return 0


def timed_validation(model_file: Path, limits: SandboxLimits, say) -> dict:
    """Load (within load_cpu_s of CPU), then the timed dry run, each call within its budget."""
    from league.agents import import_onnxruntime
    from league.validation.loading import import_torch, load_checked
    from league.validation.timing import CpuAllowance, steady_speed, timing_batches, too_slow

    if model_file.suffix == ".onnx":  # the runtime imported first, as the server's sandboxes find it
        import_onnxruntime()
    else:
        import_torch()
    start = time.thread_time()
    say(phase="loading")
    limit_cpu(limits.load_cpu_s)
    agent = load_checked(model_file, limits.memory_mb)
    if time.thread_time() - start > limits.load_cpu_s:
        return refused(load_over(limits))
    allowance = CpuAllowance(limits)
    for obs in timing_batches(agent.obs_dim):
        rows, before = obs.shape[0], time.thread_time()
        budget = allowance.for_call(rows)
        if budget <= 0:
            return refused(allowance.call_over(rows))
        say(phase="call", over=allowance.call_over(rows))
        limit_cpu(budget)
        agent(obs)  # a model that fails fails the check (main)
        used = time.thread_time() - before
        if used > budget:
            return refused(allowance.call_over(rows))
        allowance.account(used, rows)
    speed = steady_speed(allowance.per_observation)
    slow = too_slow(speed, limits)
    return {"ok": slow is None, "obs_dim": None if slow else agent.obs_dim, "error": slow,
            "cpu_ms_per_observation": speed * 1000}


def refused(reason: str) -> dict:
    return {"ok": False, "obs_dim": None, "error": reason, "cpu_ms_per_observation": None}


def limit_cpu(seconds: float) -> None:
    """Let the kernel stop this process (SIGXCPU) once it used `seconds` more CPU time (rounded up to
    the next whole second, the limit's unit); where there is no such limit the parent's backstop
    stops it. (Once the limit is set, this process's own CPU clock is only as fine as the kernel's
    tick: calls are timed with the thread's clock, the model's calls running on this thread.)"""
    try:
        import resource
    except ImportError:
        return
    usage = resource.getrusage(resource.RUSAGE_SELF)
    hard = resource.getrlimit(resource.RLIMIT_CPU)[1]
    soft = math.ceil(usage.ru_utime + usage.ru_stime + seconds) + 1
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # SIGXCPU's default action dumps core
    resource.setrlimit(resource.RLIMIT_CPU, (soft if hard == resource.RLIM_INFINITY else min(soft, hard), hard))


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:4]))
