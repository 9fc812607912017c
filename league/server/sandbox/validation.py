"""Validating an upload: static checks, load and the toolkit's dry run in a sandbox, then a timed
dry run from the worker (a model that needs more CPU per observation than its budget is rejected
before any evaluation)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from league.agents import AgentError, dry_run_observations
from league.server.sandbox.agent import SandboxedAgent
from league.server.sandbox.limits import SandboxLimits
from league.server.sandbox.log import LogBuffer

DRY_RUN_CALLS = 24  # parent-side dry run: enough calls to see a model's steady CPU use
DRY_RUN_WARMUP = 4  # calls not counted in that speed (first calls are slower)


@dataclass(frozen=True)
class ValidationReport:
    ok: bool
    obs_dim: int | None
    error: str | None
    log: str
    cpu_ms_per_observation: float | None = None


def validate_model(model_file: Path, model_kind: str, limits: SandboxLimits) -> ValidationReport:
    """Static checks, load and the toolkit's dry run (in the child), then a timed dry run from here."""
    log = LogBuffer(limits.log_limit)
    strict = SandboxLimits(**{**limits.__dict__, "max_restarts": 0})
    try:
        with SandboxedAgent(model_file, model_kind, strict, log=log) as agent:
            speed = _timed_dry_run(agent)
    except AgentError as error:
        return ValidationReport(False, None, error.reason, log.text())
    if speed > limits.step_deadline_s:
        reason = (f"the model is too slow: it uses {speed * 1000:.1f} ms of CPU per observation, the limit "
                  f"is {limits.step_deadline_s * 1000:g} ms")
        return ValidationReport(False, None, reason, log.text(), speed * 1000)
    return ValidationReport(True, agent.obs_dim, None, log.text(), speed * 1000)


def _timed_dry_run(agent: SandboxedAgent) -> float:
    """Median CPU time per observation after warm-up, on plausible, varied observations (batches
    of 1 and 4)."""
    rng = np.random.default_rng(0)
    for i in range(DRY_RUN_CALLS):
        batch = 4 if i % 6 == 5 else 1
        obs = dry_run_observations(agent.obs_dim, batch)
        agent(obs * rng.uniform(0.5, 1.5, obs.shape).astype(np.float32))
    return float(np.median(agent.cpu_per_observation[DRY_RUN_WARMUP:]))
