"""Races and championships on the server: the race job, round planning, standings and ratings.

A race job runs `league.evaluation.race` (the toolkit's, unchanged) with every car's agent in a
sandbox of its own; an agent that fails is a DNF for its car only. A championship round is
fixed when it is created -- its entrants, its heats and its track seed are stored -- and each
heat is a race job of its own, so workers share a round's heats, a dead worker's heat is raced
again by another, and a finished heat is never counted twice (see league.server.jobs).

Standings and ratings are not stored: they are recomputed from the classifications of the
finished rounds, in order, with `league.championship` (the same rules as the command line).
"""
from __future__ import annotations

import functools
import gzip
import json
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from league import championship as rules
from league.agents import COMPACT_DIM, Agent, AgentError
from league.evaluation import RaceResult, episode_seeds, race
from league.server.db import crud
from league.server.db.models import (
    BASELINE, DONE, FAILED, PENDING, RACE, READY, RUNNING, STUDENT, Championship, ChampionshipRound, Job, Race,
    RaceReplay, Submission, User, utcnow,
)
from league.server.jobs import JobRun, register_handler
from league.server.sandbox import LogBuffer, SandboxedAgent, SandboxLimits
from league.server.tasks import model_file

log = logging.getLogger("league.server.racing")

# --------------------------------------------------------------------------- the race job


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
        limits = SandboxLimits.from_settings(run.context.settings)
        logs = [LogBuffer(max(1024, limits.log_limit // len(submissions))) for _ in submissions]
        names = [car_name(entrant) for entrant in race_row.entrants]
        starters = [functools.partial(start_agent, run, limits, *car) for car in zip(submissions, names, logs)]
        try:
            result = race_in_sandboxes(starters, names, seed=race_row.seed, env_options=race_row.env_options)
        except InvalidRaceSettings as error:
            return RaceOutcome(None, None, str(error), race_log(names, logs))
        classification = [{**row, **entrant_of(race_row.entrants, row["car"])} for row in result.classification]
        return RaceOutcome(classification, result.replay, None, race_log(names, logs))

    def finish(self, session: Session, job: Job, outcome: RaceOutcome) -> list[int]:
        race_row = session.get(Race, job.race_id)
        race_row.log, race_row.finished_at = outcome.log, utcnow()
        if outcome.classification is None:
            race_row.status, race_row.error = FAILED, outcome.error
            return []
        race_row.classification, race_row.status, race_row.error = outcome.classification, DONE, None
        replay = session.get(RaceReplay, race_row.id) or RaceReplay(race_id=race_row.id)
        replay.data = gzip.compress(json.dumps(outcome.replay, separators=(",", ":")).encode(), compresslevel=6)
        session.add(replay)
        return []

    def give_up(self, session: Session, job: Job, reason: str) -> None:
        race_row = session.get(Race, job.race_id)
        race_row.status, race_row.error = FAILED, f"the race could not be completed: {reason}"
        race_row.finished_at = utcnow()


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
        try:
            result = race(agents, seed=seed, names=names, **env_options)
        except (TypeError, ValueError) as error:  # what the simulator refuses; a failed start is retried
            raise InvalidRaceSettings(f"invalid race settings: {error}") from error
        log.info("%d cars: sandboxes started in %.2f s, raced in %.2f s", len(agents), ready - began,
                 time.perf_counter() - ready)
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
        return SandboxedAgent(model_file(run, submission), submission.kind, limits, name=name, log=log,
                              cancel=run.lease_lost)
    except AgentError as error:
        return FailedAgent(submission.obs_dim or COMPACT_DIM, name, error.reason)
    except FileNotFoundError as error:
        return FailedAgent(submission.obs_dim or COMPACT_DIM, name, str(error))


def car_name(entrant: dict) -> str:
    return f"{entrant['name']} ({entrant['owner']})"


def entrant_of(entrants: list[dict], car: str) -> dict:
    entrant = entrants[int(car.removeprefix("car_"))]
    return {"submission_id": entrant["submission_id"], "name": entrant["name"], "owner": entrant["owner"]}


def race_log(names: list[str], logs: list[LogBuffer]) -> str:
    return "".join(f"== {name} ==\n{log.text()}\n" for name, log in zip(names, logs) if log.text())


def replay_json(session: Session, race_id: int) -> bytes | None:
    replay = session.get(RaceReplay, race_id)
    return None if replay is None else gzip.decompress(replay.data)


register_handler(RACE, RunRace())


# --------------------------------------------------------------------------- creating races


def entrant_info(submission: Submission) -> dict:
    return {"submission_id": submission.id, "name": submission.name, "owner": submission.owner.name}


def create_race(session: Session, *, entrants: list[Submission], seed: int, env_options: dict[str, Any],
                created_by: User | None, course_id: int | None, max_attempts: int,
                championship_round: ChampionshipRound | None = None, heat: int | None = None) -> tuple[Race, Job]:
    """A pending race and its job (callers commit, then enqueue the job)."""
    race_row = Race(course_id=course_id, created_by_id=created_by.id if created_by else None, seed=seed,
                    env_options=dict(env_options), entrants=[entrant_info(s) for s in entrants], status=PENDING,
                    championship_id=championship_round.championship_id if championship_round else None,
                    round_id=championship_round.id if championship_round else None, heat=heat)
    session.add(race_row)
    session.flush()
    job = crud.create_job(session, kind=RACE, race_id=race_row.id, max_attempts=max_attempts)
    return race_row, job


def races_started_since(session: Session, *, user: User, since) -> int:
    """Friendly races a user started in the window (the daily quota)."""
    return session.scalar(select(func.count(Race.id)).where(
        Race.created_by_id == user.id, Race.championship_id.is_(None), Race.created_at > since)) or 0


# --------------------------------------------------------------------------- championships


class RoundRefused(Exception):
    """A round cannot start now (the message says why and what to do)."""


def round_status(championship_round: ChampionshipRound) -> str:
    """pending, running, done or failed (once no heat is left to race and one failed): what its
    heats' races are."""
    statuses = [r.status for r in championship_round.races]
    if statuses and all(s == DONE for s in statuses):
        return DONE
    if not any(s in (PENDING, RUNNING) for s in statuses):
        return FAILED
    if any(s in (RUNNING, DONE, FAILED) for s in statuses):
        return RUNNING
    return PENDING


def round_summary(championship_round: ChampionshipRound) -> dict:
    races = championship_round.races
    return {"number": championship_round.number, "status": round_status(championship_round),
            "heats_done": sum(r.status == DONE for r in races), "heats_total": len(championship_round.heats),
            "race_ids": [r.id for r in races], "track_seed": championship_round.track_seed,
            "heats": championship_round.heats, "created_at": championship_round.created_at}


def round_entrants(session: Session, championship: Championship) -> list[Submission]:
    """Every student's active submission (their pick, else their latest ready one), and the
    ready baselines when they take part; in submission order."""
    students = session.scalars(select(User).where(User.course_id == championship.course_id, User.role == STUDENT,
                                                  User.revoked_at.is_(None)))
    picked = [s for s in (active_submission(session, user=u) for u in students) if s is not None]
    if championship.include_baselines:
        picked += session.scalars(select(Submission).join(User, Submission.owner_id == User.id).where(
            User.role == BASELINE, Submission.status == READY))
    return sorted(picked, key=lambda s: s.id)


def active_submission(session: Session, *, user: User) -> Submission | None:
    if user.active_submission_id is not None:
        chosen = session.get(Submission, user.active_submission_id)
        if chosen is not None and chosen.status == READY and chosen.owner_id == user.id:
            return chosen
    return session.scalar(select(Submission).where(Submission.owner_id == user.id, Submission.status == READY)
                          .order_by(Submission.id.desc()).limit(1))


def active_submission_ids(session: Session, *, owners: list[User]) -> set[int]:
    """Which submissions race in championships: each student's active one, every ready baseline."""
    active = set()
    for owner in owners:
        if owner.role == BASELINE:
            active.update(session.scalars(select(Submission.id).where(Submission.owner_id == owner.id,
                                                                      Submission.status == READY)))
        else:
            chosen = active_submission(session, user=owner)
            if chosen is not None:
                active.add(chosen.id)
    return active


def round_track_seed(championship: Championship, number: int) -> int:
    """Round n's track: the n-th number of the championship's seed sequence."""
    return episode_seeds(championship.seed, number)[number - 1]


def start_round(session: Session, *, championship: Championship, created_by: User,
                max_attempts: int) -> tuple[ChampionshipRound, list[int]]:
    """Fix the next round (entrants, seeded heats balanced by standing, track) and queue its heats."""
    for earlier in championship.rounds:
        if round_status(earlier) in (PENDING, RUNNING):
            raise RoundRefused(f"round {earlier.number} is still {round_status(earlier)}: wait for it to finish")
    entrants = round_entrants(session, championship)
    if not entrants:
        raise RoundRefused("no ready submission can race: students must upload an agent that passes validation")
    number = len(championship.rounds) + 1
    ranking = [standing.entrant for standing in championship_standings(championship)]
    heats = rules.split_into_heats([s.id for s in entrants], championship.heat_size,
                                   np.random.default_rng([championship.seed, number]), ranking=ranking)
    championship_round = ChampionshipRound(championship_id=championship.id, number=number, heats=heats,
                                           track_seed=round_track_seed(championship, number))
    session.add(championship_round)
    session.flush()
    by_id = {s.id: s for s in entrants}
    jobs = [create_race(session, entrants=[by_id[i] for i in heat], seed=championship_round.track_seed,
                        env_options=championship.env_options, created_by=created_by,
                        course_id=championship.course_id, max_attempts=max_attempts,
                        championship_round=championship_round, heat=k + 1)[1].id
            for k, heat in enumerate(heats)]
    session.expire(championship, ["rounds"])
    return championship_round, jobs


def retry_round(session: Session, *, championship: Championship, championship_round: ChampionshipRound,
                max_attempts: int) -> list[int]:
    """Queue the failed heats of a championship's latest round again (the heats that were raced
    keep their results); returns the new jobs (callers commit, then enqueue them)."""
    latest = max(r.number for r in championship.rounds)
    if championship_round.number != latest:
        raise RoundRefused(f"only the latest round can be raced again: round {latest} came after round "
                           f"{championship_round.number}")
    current = round_status(championship_round)
    if current != FAILED:
        raise RoundRefused(f"round {championship_round.number} is {current}: only a failed round is raced again")
    jobs = []
    for race_row in championship_round.races:
        if race_row.status == FAILED:
            race_row.status, race_row.error, race_row.started_at, race_row.finished_at = PENDING, None, None, None
            jobs.append(crud.create_job(session, kind=RACE, race_id=race_row.id, max_attempts=max_attempts).id)
    return jobs


def finished_heats(rounds: list[ChampionshipRound]) -> list[list[dict]]:
    """The classifications of the heats of finished rounds, in order, as the rules read them."""
    heats = []
    for championship_round in sorted(rounds, key=lambda r: r.number):
        if round_status(championship_round) != DONE:
            continue  # points are awarded when the whole round is over
        for race_row in championship_round.races:
            heats.append([{"entrant": row["submission_id"], "position": row["position"], "outcome": row["outcome"]}
                          for row in race_row.classification])
    return heats


def championship_standings(championship: Championship) -> list[rules.Standing]:
    return rules.standings(finished_heats(championship.rounds), tuple(championship.points))


def ratings_after(heats: list[list[dict]]) -> dict[int, rules.Rating]:
    """OpenSkill (Plackett-Luce) ratings, updated heat after heat from each heat's order."""
    ratings: dict[int, rules.Rating] = {}
    for heat in heats:
        order = [row["entrant"] for row in sorted(heat, key=lambda row: row["position"])]
        ratings.update(rules.update_ratings(ratings, order))
    return ratings


def standings_rows(session: Session, championship: Championship) -> list[dict]:
    heats = finished_heats(championship.rounds)
    table, ratings = rules.standings(heats, tuple(championship.points)), ratings_after(heats)
    submissions = submissions_by_id(session, [standing.entrant for standing in table])
    rows = []
    for rank, standing in enumerate(table, start=1):
        submission, rating = submissions.get(standing.entrant), ratings[standing.entrant]
        rows.append({"rank": rank, "submission_id": standing.entrant,
                     "name": submission.name if submission else "(deleted)",
                     "owner": submission.owner.name if submission else "", "points": standing.points,
                     "wins": standing.wins, "finishes": standing.finishes, "rating": rating.conservative,
                     "mu": rating.mu, "sigma": rating.sigma})
    return rows


def submissions_by_id(session: Session, ids: list[int]) -> dict[int, Submission]:
    if not ids:
        return {}
    return {s.id: s for s in session.scalars(select(Submission).where(Submission.id.in_(ids)))}


def course_ratings(session: Session, *, course_id: int | None) -> dict[int, rules.Rating]:
    """Ratings from every finished round of the course's championships, oldest first."""
    championships = session.scalars(select(Championship).where(Championship.course_id == course_id)
                                     .order_by(Championship.id))
    rounds = sorted((r for c in championships for r in c.rounds), key=lambda r: r.id)
    heats = []
    for championship_round in rounds:
        heats += finished_heats([championship_round])
    return ratings_after(heats)


# --------------------------------------------------------------------------- the course leaderboard


def leaderboard_rows(session: Session, *, course_id: int | None) -> list[dict]:
    """Each student's best evaluated submission (completion rate, then mean return), and every
    bundled baseline as a reference row; best first, with the course-wide rating."""
    owners = list(session.scalars(select(User).where(
        ((User.course_id == course_id) & (User.role == STUDENT) & User.revoked_at.is_(None)) | (User.role == BASELINE))))
    submissions = crud.submissions_of(session, owner_ids=[u.id for u in owners])
    ready = [s for s in submissions if s.status == READY]
    # the newest finished evaluation: a re-run in progress does not take an agent off the board
    evaluations = crud.latest_evaluations(session, submission_ids=[s.id for s in ready], status=DONE)
    evaluated = [(s, evaluations[s.id]) for s in ready if s.id in evaluations]
    best: dict[object, tuple[Submission, Any]] = {}
    for submission, evaluation in evaluated:
        key = submission.id if submission.owner.role == BASELINE else submission.owner_id
        if key not in best or _score(evaluation) > _score(best[key][1]):
            best[key] = (submission, evaluation)
    ratings = course_ratings(session, course_id=course_id)
    ordered = sorted(best.values(), key=lambda pair: (_score(pair[1]), -pair[0].id), reverse=True)
    return [_leaderboard_row(rank, submission, evaluation, ratings.get(submission.id))
            for rank, (submission, evaluation) in enumerate(ordered, start=1)]


def _score(evaluation) -> tuple[float, float]:
    return (evaluation.completed / max(evaluation.episodes_total, 1), evaluation.mean_return)


def _leaderboard_row(rank: int, submission: Submission, evaluation, rating: rules.Rating | None) -> dict:
    return {"rank": rank, "owner": submission.owner.name, "submission_id": submission.id, "name": submission.name,
            "public": submission.public, "completed": evaluation.completed, "episodes": evaluation.episodes_total,
            "mean_return": evaluation.mean_return, "mean_steps": evaluation.mean_steps,
            "mean_speed": evaluation.mean_speed, "rating": rating.conservative if rating else None,
            "mu": rating.mu if rating else None, "sigma": rating.sigma if rating else None}
