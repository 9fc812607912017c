"""Validating an upload: the toolkit's static checks, load and dry run in a sandbox, then its timed
dry run from the worker (league.validation.timing: a model that needs more CPU per observation
than its budget is rejected before any evaluation). `league check` runs the same steps on a
student's machine without the sandbox (league.validation.local)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from league.agents import AgentError
from league.server.sandbox.agent import SandboxedAgent
from league.server.sandbox.log import LogBuffer
from league.validation.limits import SandboxLimits
from league.validation.report import ValidationReport
from league.validation.timing import steady_speed, timing_batches, too_slow


def validate_model(model_file: Path, model_kind: str, limits: SandboxLimits) -> ValidationReport:
    """Static checks, load and the toolkit's dry run (in the child), then a timed dry run from here."""
    log = LogBuffer(limits.log_limit)
    try:
        with SandboxedAgent(model_file, model_kind, replace(limits, max_restarts=0), log=log) as agent:
            for obs in timing_batches(agent.obs_dim):
                agent(obs)
    except AgentError as error:
        return ValidationReport(False, None, error.reason, log.text())
    speed = steady_speed(agent.cpu_per_observation)
    slow = too_slow(speed, limits)
    return ValidationReport(slow is None, None if slow else agent.obs_dim, slow, log.text(), speed * 1000)
