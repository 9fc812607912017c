"""The race job: the toolkit's `league.evaluation.race`, unchanged, with every car's agent in a
sandbox of its own; an agent that fails is a DNF for its car only. Championship heats are race
jobs too (league.server.course.races), so workers share a round and a heat is counted once."""
from __future__ import annotations

import dataclasses
import functools
import gzip
import json
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from league.agents import COMPACT_DIM, Agent, AgentError
from league.evaluation import RaceResult, race
from league.track import TrackGenerationError
from league.server.core.clock import utcnow
from league.server.db.models import DONE, FAILED, RUNNING, Job, Race, RaceReplay, Submission
from league.server.jobs.runner import JobCannotSucceed, JobRun
from league.server.sandbox.agent import SandboxedAgent
from league.server.sandbox.log import LogBuffer
from league.validation.limits import SandboxLimits

log = logging.getLogger("league.server.race")


class FailedAgent(Agent):
    """A car whose agent could not start: it is a DNF with the reason before the start."""

    def __init__(self, obs_dim: int, name: str, reason: str):
        super().__init__(obs_dim, name)
        self.reason = reason

    def reset(self) -> None:
        raise AgentError(self.reason)

    def _act(self, obs: np.ndarray) -> np.ndarray:
        raise AgentError(self.reason)


@dataclass
class RaceOutcome:
    classification: list[dict] | None
    replay: dict | None
    error: str | None
    log: str


class RunRace:
    parallel_sandboxes = True  # every car is asked before any answer is awaited

    def begin(self, session: Session, job: Job) -> None:
        race_row = session.get(Race, job.race_id)
        race_row.status, race_row.error, race_row.started_at = RUNNING, None, utcnow()

    def run(self, run: JobRun) -> RaceOutcome:
        with run.context.sessions() as session:
            race_row = session.get(Race, run.job.race_id)
            submissions = [session.get(Submission, e["submission_id"]) for e in race_row.entrants]
        limits = car_limits(run.context.settings.sandbox_limits(), len(submissions),
                            run.context.settings.race_memory_mb)
        logs = [LogBuffer(max(1024, limits.log_limit // len(submissions))) for _ in submissions]
        names = [car_name(entrant) for entrant in race_row.entrants]
        starters = [functools.partial(start_agent, run, limits, *car) for car in zip(submissions, names, logs)]
        try:
            result = race_in_sandboxes(starters, names, seed=race_row.seed, env_options=race_row.env_options)
        except InvalidRaceSettings as error:
            return RaceOutcome(None, None, str(error), race_log(names, logs))
        full = [{**row, **entrant_of(race_row.entrants, row["car"])} for row in result.classification]
        replay = {**result.replay, "classification": public(result.replay["classification"])}
        return RaceOutcome(public(full), replay, None, race_log(names, logs))  # logs: the reasons in full

    def finish(self, session: Session, job: Job, outcome: RaceOutcome) -> list[int]:
        race_row = session.get(Race, job.race_id)
        race_row.log, race_row.finished_at = outcome.log, utcnow()
        if outcome.classification is None:
            race_row.status, race_row.error = FAILED, outcome.error
            return []
        race_row.classification, race_row.status, race_row.error = outcome.classification, DONE, None
        race_row.versions = outcome.replay["versions"]  # the worker's simulator and package
        replay = session.get(RaceReplay, race_row.id) or RaceReplay(race_id=race_row.id)
        replay.data = gzip.compress(json.dumps(outcome.replay, separators=(",", ":")).encode(), compresslevel=6)
        session.add(replay)
        return []

    def give_up(self, session: Session, job: Job, reason: str) -> None:
        race_row = session.get(Race, job.race_id)
        race_row.status, race_row.error = FAILED, f"the race could not be completed: {reason}"
        race_row.finished_at = utcnow()


def car_limits(limits: SandboxLimits, cars: int, race_memory_mb: int) -> SandboxLimits:
    """Each car's sandbox limits: the race's memory shared between its cars (a sandbox's own cap
    is also kept)."""
    return dataclasses.replace(limits, memory_mb=min(limits.memory_mb, race_memory_mb // max(cars, 1)))


class InvalidRaceSettings(Exception):
    """Options the simulator refuses: racing again cannot help."""


def race_in_sandboxes(starters: Sequence[Callable[[], Agent]], names: list[str], *, seed: int,
                      env_options: dict[str, Any]) -> RaceResult:
    """Start every car's agent (`starters`, e.g. `start_agent` or `SandboxedAgent` partials), race
    them with the toolkit's `race`, then close them all, whatever happened."""
    began = time.perf_counter()
    agents: list[Agent] = []
    try:
        for start in starters:  # from this thread: a sandbox dies with the thread that started it (PDEATHSIG)
            agents.append(start())
        ready = time.perf_counter()
        log.info("%d cars: sandboxes started in %.2f s, racing", len(agents), ready - began)
        try:
            result = race(agents, seed=seed, names=names, **env_options)
        except (TypeError, ValueError, TrackGenerationError) as error:  # what the simulator refuses
            raise InvalidRaceSettings(f"invalid race settings: {error}") from error
        log.info("%d cars raced in %.2f s", len(agents), time.perf_counter() - ready)
        return result
    finally:
        for agent in agents:
            agent.close()


def start_agent(run: JobRun, limits: SandboxLimits, submission: Submission | None, name: str,
                log: LogBuffer) -> Agent:
    """The car's agent in its own sandbox, or a FailedAgent saying why it could not start."""
    if submission is None:
        return FailedAgent(COMPACT_DIM, name, "the submission no longer exists")
    try:
        return SandboxedAgent(run.model_file(submission), submission.kind, limits, name=name, log=log,
                              cancel=run.lease_lost)
    except AgentError as error:
        return FailedAgent(submission.obs_dim or COMPACT_DIM, name, error.reason)
    except JobCannotSucceed as error:  # its file is gone: this car cannot start, the others race
        return FailedAgent(submission.obs_dim or COMPACT_DIM, name, str(error))


def public(classification: list[dict]) -> list[dict]:
    """The classification as everyone may see it: a DNF's reason up to its details, which are the
    model's own words (an exception's message, code); the race log keeps them for instructors."""
    return [{**row, "reason": row["reason"].split(": ", 1)[0]} if row["outcome"] == "dnf" and row["reason"] else row
            for row in classification]


def car_name(entrant: dict) -> str:
    return f"{entrant['name']} ({entrant['owner']})"


def entrant_of(entrants: list[dict], car: str) -> dict:
    entrant = entrants[int(car.removeprefix("car_"))]
    return {"submission_id": entrant["submission_id"], "name": entrant["name"], "owner": entrant["owner"]}


def race_log(names: list[str], logs: list[LogBuffer]) -> str:
    return "".join(f"== {name} ==\n{log.text()}\n" for name, log in zip(names, logs) if log.text())
