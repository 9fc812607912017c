"""An Agent whose model runs in a sandbox process: deadlines, restarts, cancellation.

`SandboxedAgent` is a `league.agents.Agent`, so the worker runs the toolkit's `metrics_run` and
`race` on it unchanged. Each call sends the observation batch as raw float32 bytes and waits for
the actions under a deadline: `step_deadline` per call, plus a bank of `first_call_allowance`
spent by calls that overrun it (warm-up, JIT). A call past its deadline, a crash, a NaN or a model
exception raises `AgentError(reason)` -- a DNF -- and a dead or killed child is restarted for the
next call, at most `max_restarts` times.
"""
from __future__ import annotations

import functools
import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np

from league.agents import Agent, AgentError, check_actions
from league.server.sandbox.limits import SandboxLimits
from league.server.sandbox.log import LogBuffer
from league.server.sandbox.process import SandboxFailure, SandboxProcess


class SandboxedAgent(Agent):
    """An Agent whose model runs in a sandbox process, with deadlines and restarts (see module doc)."""

    kind = "sandbox"

    def __init__(self, model_file: Path, model_kind: str, limits: SandboxLimits, *, name: str = "submission",
                 log: LogBuffer | None = None, cancel: threading.Event | None = None):
        self.limits, self.model_file, self.model_kind = limits, Path(model_file), model_kind
        self.log = log or LogBuffer(limits.log_limit)
        self.cancel = cancel or threading.Event()
        self.restarts, self.last_failure = 0, None
        self.call_times: list[float] = []
        self._process: SandboxProcess | None = None
        ready = self._start()
        super().__init__(ready["obs_dim"], name)
        self.isolation = ready["isolation"]
        self.episode_time = 0.0

    def _start(self) -> dict:
        try:
            self._process = SandboxProcess(self.model_file, self.model_kind, self.limits, self.log)
        except SandboxFailure as failure:
            self._process = None
            self.log.note(f"refused: {failure.reason}")
            raise AgentError(failure.reason) from failure
        self.bank = self.limits.first_call_allowance_s
        isolation = self._process.ready["isolation"]
        self.log.note(f"started: Landlock ABI {isolation['landlock']}, seccomp, network {isolation['network']}, "
                      f"runs as {isolation['user']}, memory cap +{self.limits.memory_mb} MB, "
                      f"step deadline {self.limits.step_deadline_s * 1000:g} ms")
        return self._process.ready

    def new_episode(self) -> None:
        """Reset the per-episode clock (metrics_run's on_episode calls it)."""
        self.episode_time = 0.0

    def _act(self, obs: np.ndarray) -> np.ndarray:
        return self._send(obs)()

    def request(self, obs: np.ndarray) -> Callable[[], np.ndarray]:
        """Send the observations now; the result reads the answer (a race asks all its cars first)."""
        obs = self._check_observations(obs)
        try:
            receive = self._send(obs)
        except AgentError as error:
            return functools.partial(_raise, error)
        return lambda: check_actions(receive(), batch=obs.shape[0])

    def _send(self, obs: np.ndarray) -> Callable[[], np.ndarray]:
        """Send a batch; return the function that waits for its answer within the call's budget."""
        if self.cancel.is_set():
            raise AgentError("the evaluation was cancelled")
        process = self._live_process()
        episode_left = self.limits.episode_deadline_s - self.episode_time
        if episode_left <= 0:
            raise AgentError(f"the model used more than {self.limits.episode_deadline_s:g} s in this episode")
        budget = min(self.limits.step_deadline_s + self.bank, episode_left)
        started = time.monotonic()
        try:
            process.send_observations(obs)
        except SandboxFailure as failure:
            self._account(time.monotonic() - started)
            raise AgentError(self._failure_reason(failure, budget, episode_left)) from failure

        def receive() -> np.ndarray:
            try:
                return process.receive_actions(started + budget)
            except SandboxFailure as failure:
                raise AgentError(self._failure_reason(failure, budget, episode_left)) from failure
            finally:
                self._account(time.monotonic() - started)

        return receive

    def _account(self, elapsed: float) -> None:
        self.call_times.append(elapsed)
        self.episode_time += elapsed
        self.bank = max(0.0, self.bank - max(0.0, elapsed - self.limits.step_deadline_s))

    def _failure_reason(self, failure: SandboxFailure, budget: float, episode_left: float) -> str:
        if failure.fatal:
            self._process.close()
            self._process = None
        if not failure.timed_out:
            reason = failure.reason
        elif budget >= episode_left:
            reason = f"the model used more than {self.limits.episode_deadline_s:g} s in this episode"
        else:
            reason = (f"the model did not answer within its {self.limits.step_deadline_s * 1000:g} ms step deadline "
                      f"(allowance left: {self.bank * 1000:.0f} ms)")
        self.last_failure = reason
        self.log.note(reason)
        return reason

    def _live_process(self) -> SandboxProcess:
        if self._process is not None:
            return self._process
        if self.restarts >= self.limits.max_restarts:
            raise AgentError(f"the agent was stopped after {self.restarts + 1} failures; last: {self.last_failure}")
        self.restarts += 1
        self._start()
        return self._process

    def close(self) -> None:
        if self._process is not None:
            self._process.close()
            self._process = None


def _raise(error: Exception):
    raise error


# --------------------------------------------------------------------------- validation
