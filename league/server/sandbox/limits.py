"""What a sandbox may use: memory, CPU time, time per call and per episode, restarts, log size."""
from __future__ import annotations

from dataclasses import dataclass

from league.server.config import Settings


@dataclass(frozen=True)
class SandboxLimits:
    memory_mb: int = 512
    cpu_seconds: int = 600
    step_deadline_s: float = 0.020
    first_call_allowance_s: float = 1.0
    episode_deadline_s: float = 60.0
    load_timeout_s: float = 30.0
    uid_base: int = 0x5000_0000  # a sandbox of a root server runs as uid_base + its pid; 0: root, no capabilities
    require_isolation: bool = True  # refuse to run a model without Landlock and seccomp
    max_restarts: int = 3
    log_limit: int = 16 * 1024

    @classmethod
    def from_settings(cls, settings: Settings) -> SandboxLimits:
        return cls(memory_mb=settings.sandbox_memory_mb, cpu_seconds=settings.sandbox_cpu_seconds,
                   step_deadline_s=settings.step_deadline_ms / 1000,
                   first_call_allowance_s=settings.first_call_allowance_ms / 1000,
                   episode_deadline_s=settings.episode_deadline_s, load_timeout_s=settings.load_timeout_s,
                   uid_base=settings.sandbox_uid_base, require_isolation=settings.sandbox_require_isolation,
                   max_restarts=settings.sandbox_max_restarts,
                   log_limit=settings.log_limit_kb * 1024)
