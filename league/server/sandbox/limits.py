"""What a sandbox may use: memory, CPU time per observation, per run and to load, restarts, log size."""
from __future__ import annotations

from dataclasses import dataclass

from league.server.config import Settings


@dataclass(frozen=True)
class SandboxLimits:
    memory_mb: int = 512
    cpu_seconds: int = 600
    # CPU time of the sandbox process (the same on a quiet machine and a busy one), not wall time
    step_deadline_s: float = 0.020  # per observation of a call
    first_call_allowance_s: float = 1.0  # banked for calls over their budget (warm-up, JIT)
    run_cpu_s: float = 60.0  # all the calls of one evaluation or race
    load_cpu_s: float = 30.0  # starting, loading the model and its dry run
    uid_base: int = 0x5000_0000  # a sandbox of a root server runs as uid_base + its pid; 0: root, no capabilities
    require_isolation: bool = True  # refuse to run a model without Landlock and seccomp
    max_restarts: int = 3
    log_limit: int = 16 * 1024

    @classmethod
    def from_settings(cls, settings: Settings) -> SandboxLimits:
        return cls(memory_mb=settings.sandbox_memory_mb, cpu_seconds=settings.sandbox_cpu_seconds,
                   step_deadline_s=settings.step_deadline_ms / 1000,
                   first_call_allowance_s=settings.first_call_allowance_ms / 1000,
                   run_cpu_s=settings.run_cpu_s, load_cpu_s=settings.load_cpu_s,
                   uid_base=settings.sandbox_uid_base, require_isolation=settings.sandbox_require_isolation,
                   max_restarts=settings.sandbox_max_restarts,
                   log_limit=settings.log_limit_kb * 1024)
