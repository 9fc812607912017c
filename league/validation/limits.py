"""What an uploaded model may use: memory, CPU time per observation, per run and to load; and,
for the server's sandboxes, their user ids, isolation, restarts and log size.

The league's defaults live here, once: a server's settings (league.server.core.config) default to
them, and `league check` uses them when no server says otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass

MAX_UPLOAD_MB = 10.0  # the largest model file a league accepts by default


@dataclass(frozen=True)
class SandboxLimits:
    memory_mb: int = 512  # address space a model may use on top of its runtime
    cpu_seconds: int = 600  # CPU time of one sandbox process
    # CPU time of the model (the same on a quiet machine and a busy one), not wall time
    step_deadline_s: float = 0.020  # per observation of a call
    first_call_allowance_s: float = 1.0  # banked for calls over their budget (warm-up, JIT)
    run_cpu_s: float = 60.0  # all the calls of one evaluation or race
    load_cpu_s: float = 30.0  # starting, loading the model and its dry run
    uid_base: int = 0x5000_0000  # a sandbox of a root server runs as uid_base + its pid; 0: root, no capabilities
    require_isolation: bool = True  # refuse to run a model without Landlock and seccomp
    max_restarts: int = 3
    log_limit: int = 16 * 1024  # bytes of what a sandbox printed, kept per run
