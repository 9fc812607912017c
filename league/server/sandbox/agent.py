"""An Agent whose model runs in a sandbox process: deadlines, restarts, cancellation.

`SandboxedAgent` is a `league.agents.Agent`, so the worker runs the toolkit's `metrics_run` and
`race` on it unchanged. Each call sends the observation batch as raw float32 bytes and waits for
the actions within a budget of the child's own CPU time: `step_deadline` per observation, plus a
bank of `first_call_allowance` spent by calls that overrun it (warm-up, JIT), within `run_cpu`
for the whole run. CPU time, not wall time: a model gets the same result on a quiet machine and
on a busy one. A call over its budget, a crash, a NaN or a model exception raises
`AgentError(reason)` -- a DNF -- and a dead or killed child is restarted for the next call, at
most `max_restarts` times. A NaN or an exception of the model is isolable (the sandbox answered):
an evaluation fails only the observations that fail, as in process.
"""
from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from league.agents import Agent, AgentError, check_actions
from league.server.sandbox.log import LogBuffer
from league.server.sandbox.process import WALL_BACKSTOP, WALL_MARGIN_S, Budget, SandboxFailure, SandboxProcess
from league.validation.limits import SandboxLimits
from league.validation.timing import CpuAllowance, run_spent


class SandboxedAgent(Agent):
    """An Agent whose model runs in a sandbox process, with deadlines and restarts (see module doc)."""

    kind = "sandbox"

    def __init__(self, model_file: Path, model_kind: str, limits: SandboxLimits, *, name: str = "submission",
                 log: LogBuffer | None = None, cancel: threading.Event | None = None):
        self.limits, self.model_file, self.model_kind = limits, Path(model_file), model_kind
        self.log = log or LogBuffer(limits.log_limit)
        self.cancel = cancel or threading.Event()
        self.restarts, self.last_failure = 0, None
        self.allowance = CpuAllowance(limits)  # the CPU time of each call, over the run
        self._process: SandboxProcess | None = None
        ready = self._start()
        super().__init__(ready["obs_dim"], name)
        self.isolation = ready["isolation"]

    def _start(self) -> dict:
        try:
            self._process = SandboxProcess(self.model_file, self.model_kind, self.limits, self.log)
        except SandboxFailure as failure:
            self._process = None
            self.log.note(f"refused: {failure.reason}")
            raise AgentError(failure.reason) from failure
        self.allowance.refill()  # a new process warms up again
        isolation = self._process.ready["isolation"]
        self.log.note(f"started: Landlock ABI {isolation['landlock']}, seccomp, network {isolation['network']}, "
                      f"runs as {isolation['user']}, memory cap +{self.limits.memory_mb} MB, "
                      f"{self.limits.step_deadline_s * 1000:g} ms of CPU per observation")
        return self._process.ready

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
        process = self._process or self._live_process()
        allowance = self.allowance
        if allowance.run_left() <= 0:
            raise AgentError(run_spent(self.limits))
        rows = obs.shape[0]
        budget = Budget(process.cpu_time, cpu_s := allowance.for_call(rows), WALL_BACKSTOP * cpu_s + WALL_MARGIN_S)
        try:
            process.send_observations(obs)
        except SandboxFailure as failure:
            reason = self._failure_reason(failure, budget, rows)  # (before the call is accounted)
            allowance.account(budget.used(), rows)
            raise AgentError(reason) from failure

        def receive() -> np.ndarray:
            try:
                return process.receive_actions(budget)
            except SandboxFailure as failure:
                # the model's own failure on these observations (an answer, the sandbox lives on) is
                # isolable, as in-process: metrics_run asks again row by row and fails only the rows
                # that fail, as `league evaluate` does
                raise AgentError(self._failure_reason(failure, budget, rows), isolable=not failure.fatal) from failure
            finally:
                allowance.account(budget.used(), rows)

        return receive

    @property
    def cpu_per_observation(self) -> list[float]:
        """Seconds of CPU per observation of each call."""
        return self.allowance.per_observation

    @property
    def cpu_used(self) -> float:
        """Seconds of CPU of the calls of this run."""
        return self.allowance.used

    def _failure_reason(self, failure: SandboxFailure, budget: Budget, rows: int) -> str:
        """Why the call failed; asked before the call is accounted (the allowance it had)."""
        if failure.fatal:
            self._process.close()
            self._process = None
        if not failure.timed_out:
            reason = failure.reason
        elif budget.spent_on_the_wall_clock():
            reason = (f"the model stopped answering without using the CPU "
                      f"(no answer after {budget.wall_s:g} s)")
        else:
            reason = self.allowance.call_over(rows)  # why a call that used up its budget failed
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
