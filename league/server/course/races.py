"""Races on the server, friendly ones and championship rounds' heats: creating a race (`create_race`,
for both), fixing a round's entrants, heats and track, and which submission of a student races.

A round is fixed when it is created -- its entrants, its heats and its track seed are stored --
and each heat is a race job (league.server.jobs.race), so workers share a round's heats, a dead
worker's heat is raced again by another, and a finished heat is never counted twice. The track
seed is drawn secretly and kept out of every answer until the round is over (`track_sealed`), so
no one can rehearse a round's track before its cars have driven it.
"""
from __future__ import annotations

import secrets
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from league import championship as rules
from league.server.course.assignments import final_choices
from league.server.db import crud
from league.server.db.models import (
    BASELINE, DONE, FAILED, PENDING, RACE, READY, RUNNING, Assignment, Championship, ChampionshipRound, Job, Race,
    Submission, User,
)
from league.server.course.standings import championship_standings


class RoundRefused(Exception):
    """A round cannot start now (the message says why and what to do)."""


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
    job = crud.create_job(session, kind=RACE, owner_id=race_row.created_by_id, race_id=race_row.id,
                          max_attempts=max_attempts)
    return race_row, job


# --------------------------------------------------------------------------- which submission races


def active_submission(session: Session, *, user: User) -> Submission | None:
    """The submission a student races in championships: their pick, else their latest ready one."""
    if user.active_submission_id is not None:
        chosen = crud.ready_submission_of(session, owner_id=user.id, submission_id=user.active_submission_id)
        if chosen is not None:
            return chosen
    return crud.latest_ready_submission(session, owner_id=user.id)


def active_submission_ids(session: Session, *, owners: list[User]) -> set[int]:
    """Which submissions race in championships: each student's active one, every ready baseline."""
    active = set()
    for owner in owners:
        if owner.role == BASELINE:
            active.update(s.id for s in crud.ready_submissions(session, owner_ids=[owner.id]))
        else:
            chosen = active_submission(session, user=owner)
            if chosen is not None:
                active.add(chosen.id)
    return active


# --------------------------------------------------------------------------- rounds


def round_summary(championship_round: ChampionshipRound) -> dict:
    races = championship_round.races
    return {"number": championship_round.number, "status": championship_round.status,
            "heats_done": sum(r.status == DONE for r in races), "heats_total": len(championship_round.heats),
            "race_ids": [r.id for r in races],
            "track_seed": None if track_sealed(championship_round) else championship_round.track_seed,
            "heats": championship_round.heats, "created_at": championship_round.created_at}


def draw_track_seed() -> int:
    """A new round's track, drawn secretly: nothing published before the round derives it. Below
    2**53, so that the pages' JavaScript numbers show it exactly once it is shown."""
    return secrets.randbelow(2**53)


def track_sealed(championship_round: ChampionshipRound) -> bool:
    """Whether a round's track is still secret: while its heats are being raced, so that no one
    learns it before every heat's cars have driven it (shown once the round is done or failed)."""
    return championship_round.status in (PENDING, RUNNING)


def round_entrants(session: Session, championship: Championship) -> list[Submission]:
    """Every student's submission that races -- their final choice of the championship's assignment
    (the rule of the private test and the grades), else their active one -- and the ready baselines
    when they take part; in submission order."""
    students = crud.active_students(session, course_id=championship.course_id)
    if championship.assignment_id is not None:
        assignment = session.get(Assignment, championship.assignment_id)
        chosen = final_choices(session, assignment, [u.id for u in students]).values()
        picked = [s for s in (session.get(Submission, i) for i in chosen if i is not None) if s.status == READY]
    else:
        picked = [s for s in (active_submission(session, user=u) for u in students) if s is not None]
    if championship.include_baselines:
        picked += crud.ready_baseline_submissions(session)
    return sorted(picked, key=lambda s: s.id)


def start_round(session: Session, *, championship: Championship, created_by: User,
                max_attempts: int) -> tuple[ChampionshipRound, list[int]]:
    """Fix the next round (entrants, heats drawn from the championship's seed and balanced by
    standing, a secretly drawn track) and queue its heats."""
    for earlier in championship.rounds:
        if earlier.status in (PENDING, RUNNING):
            raise RoundRefused(f"round {earlier.number} is still {earlier.status}: wait for it to finish")
    entrants = round_entrants(session, championship)
    if not entrants:
        raise RoundRefused("no ready submission can race: students must upload an agent that passes validation")
    number = len(championship.rounds) + 1
    ranking = [standing.entrant for standing in championship_standings(championship)]
    heats = rules.split_into_heats([s.id for s in entrants], championship.heat_size,
                                   np.random.default_rng([championship.seed, number]), ranking=ranking)
    championship_round = ChampionshipRound(championship_id=championship.id, number=number, heats=heats,
                                           track_seed=draw_track_seed())
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
    current = championship_round.status
    if current != FAILED:
        raise RoundRefused(f"round {championship_round.number} is {current}: only a failed round is raced again")
    jobs = []
    for race_row in championship_round.races:
        if race_row.status == FAILED:
            race_row.status, race_row.error, race_row.started_at, race_row.finished_at = PENDING, None, None, None
            jobs.append(crud.create_job(session, kind=RACE, owner_id=race_row.created_by_id, race_id=race_row.id,
                                        max_attempts=max_attempts).id)
    return jobs
