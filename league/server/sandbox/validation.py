"""Validating an upload: the toolkit's static checks, load and dry run in a sandbox, then its timed
dry run from the worker (league.validation.timing: a model that needs more CPU per observation
than its budget is rejected before any evaluation), then its actions on the probe set, which the
integrity report compares (league.validation.probes). `league check` runs the same steps but the
probe on a student's machine without the sandbox (league.validation.local)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from league.agents import Agent, AgentError
from league.server.sandbox.agent import SandboxedAgent
from league.server.sandbox.log import LogBuffer
from league.validation.limits import SandboxLimits
from league.validation.probes import (
    Probe, observations_key, probe_actions_bytes, probe_key, probe_observations,
)
from league.validation.report import ValidationReport
from league.validation.timing import steady_speed, timing_batches, too_slow


def validate_model(model_file: Path, model_kind: str, limits: SandboxLimits) -> ValidationReport:
    """Static checks, load and the toolkit's dry run (in the child), a timed dry run from here, and
    the probe set's actions (of an accepted model)."""
    log = LogBuffer(limits.log_limit)
    try:
        with SandboxedAgent(model_file, model_kind, replace(limits, max_restarts=0), log=log) as agent:
            for obs in timing_batches(agent.obs_dim):
                agent(obs)
            speed = steady_speed(agent.cpu_per_observation)
            slow = too_slow(speed, limits)
            probe = None if slow else probe_agent(agent, log)
    except AgentError as error:
        return ValidationReport(False, None, error.reason, log.text())
    return ValidationReport(slow is None, None if slow else agent.obs_dim, slow, log.text(), speed * 1000, probe)


def probe_model(model_file: Path, model_kind: str, obs_dim: int, limits: SandboxLimits, *, name: str,
                cancel=None, secret_sets: tuple[np.ndarray, ...] = ()) -> tuple[list[Probe], str]:
    """The probe set's actions of a validated model, in a sandbox of its own (the submissions
    validated before probes were recorded), or with `secret_sets` its actions on each of those
    (assignments' secret sets) instead; and what the sandbox printed (for instructors only when
    secret: the model saw private-track observations)."""
    log = LogBuffer(limits.log_limit)
    keys = [observations_key(obs) for obs in secret_sets] or [probe_key(obs_dim)]
    try:
        with SandboxedAgent(model_file, model_kind, replace(limits, max_restarts=0), name=name, log=log,
                            cancel=cancel) as agent:
            if not secret_sets:
                return [probe_agent(agent, log)], log.text()
            return [probe_agent(agent, log, obs) for obs in secret_sets], log.text()
    except AgentError as error:  # it no longer starts
        return [Probe(key, None, error.reason) for key in keys], log.text()


def probe_agent(agent: Agent, log: LogBuffer, observations: np.ndarray | None = None) -> Probe:
    """The agent's actions on the probe set (or on `observations`, a secret set); a model that
    fails on it is not refused for that (evaluations decide what its failures cost), only left out
    of the behaviour comparison."""
    obs = probe_observations(agent.obs_dim) if observations is None else observations
    key = probe_key(agent.obs_dim) if observations is None else observations_key(observations)
    try:
        return Probe(key, probe_actions_bytes(agent(obs)))
    except AgentError as error:
        log.note(f"no actions on the integrity report's probe set: {error.reason}")
        return Probe(key, None, error.reason)
