"""CPU time a model may use, and how its speed is measured: the same rules in the server's sandbox
(league.server.sandbox.agent) and in `league check` (league.validation.local).

CPU time of the model's process, not wall time: a model gets the same verdict on a quiet machine
and on a busy one. Each call may use `step_deadline` per observation plus a bank of
`first_call_allowance`, which calls over their share spend (warm-up, JIT), within `run_cpu` for
the whole run. A model's speed is the median CPU time per observation of DRY_RUN_CALLS calls on
plausible, varied observations (batches of 1 and 4), after DRY_RUN_WARMUP calls.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from league.agents import dry_run_observations
from league.validation.limits import SandboxLimits

DRY_RUN_CALLS = 24  # enough calls to see a model's steady CPU use
DRY_RUN_WARMUP = 4  # calls not counted in that speed (first calls are slower)


@dataclass
class CpuAllowance:
    """The CPU time the next call of a model may use, and what its calls used."""

    limits: SandboxLimits
    bank: float = field(init=False)  # seconds left of the first-call allowance
    used: float = 0.0  # by the calls of this run
    per_observation: list[float] = field(default_factory=list)  # of each call

    def __post_init__(self):
        self.refill()

    def refill(self) -> None:
        self.bank = self.limits.first_call_allowance_s

    def run_left(self) -> float:
        return self.limits.run_cpu_s - self.used

    def for_call(self, rows: int) -> float:
        """Seconds of CPU a call of `rows` observations may use."""
        return min(self.limits.step_deadline_s * rows + self.bank, self.run_left())

    def account(self, used: float, rows: int) -> None:
        self.per_observation.append(used / rows)
        self.used += used
        self.bank = max(0.0, self.bank - max(0.0, used - self.limits.step_deadline_s * rows))

    def call_over(self, rows: int) -> str:
        """Why a call of `rows` observations that used up its budget failed (asked before `account`)."""
        if self.for_call(rows) >= self.run_left():
            return run_spent(self.limits)
        return (f"the model used more than its {self.limits.step_deadline_s * 1000:g} ms of CPU per "
                f"observation (allowance left: {self.bank * 1000:.0f} ms)")


def run_spent(limits: SandboxLimits) -> str:
    return f"the model used more than {limits.run_cpu_s:g} s of CPU time in this run"


def load_over(limits: SandboxLimits) -> str:
    return (f"the model did not load and pass its dry run within {limits.load_cpu_s:g} s of CPU time (a model "
            f"may use {limits.step_deadline_s * 1000:g} ms per observation)")


def timing_batches(obs_dim: int) -> Iterator[np.ndarray]:
    """The observations of the timed dry run, the same for every model of a size."""
    rng = np.random.default_rng(0)
    for i in range(DRY_RUN_CALLS):
        obs = dry_run_observations(obs_dim, 4 if i % 6 == 5 else 1)
        yield obs * rng.uniform(0.5, 1.5, obs.shape).astype(np.float32)


def steady_speed(per_observation: list[float]) -> float:
    """Seconds of CPU per observation, after warm-up."""
    return float(np.median(per_observation[DRY_RUN_WARMUP:]))


def too_slow(speed: float, limits: SandboxLimits) -> str | None:
    if speed <= limits.step_deadline_s:
        return None
    return (f"the model is too slow: it uses {speed * 1000:.1f} ms of CPU per observation, the limit "
            f"is {limits.step_deadline_s * 1000:g} ms")
