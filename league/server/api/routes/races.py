"""Races: friendly races between ready submissions, and the championship heats; their replays."""
from __future__ import annotations

import secrets
import zlib
from collections.abc import Iterator
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Request, Response, status
from fastapi.responses import PlainTextResponse, StreamingResponse
from sqlalchemy.orm import Session

from league.server.api.deps import (
    MAX_ID, CurrentUser, Id, InstructorUser, OptionalUser, PageNumber, PageSize, QueueDep, SessionDep, SettingsDep,
    board_course, board_names, check_env_options, check_jobs_in_flight, lock_account,
)
from league.server.db import crud
from league.server.db.models import (
    BASELINE, DONE, FAILED, READY, STUDENT, ChampionshipRound, Race, RaceReplay, Submission, User, utcnow,
)
from league.server.api.schemas import RaceCreate, RaceCreated, RaceOut, RacePage
from league.server.course.privacy import Names
from league.server.course.races import create_race, track_sealed

router = APIRouter(prefix="/races", tags=["races"])


@router.post("", response_model=RaceCreated, status_code=status.HTTP_201_CREATED)
def create_friendly_race(body: RaceCreate, user: CurrentUser, session: SessionDep, settings: SettingsDep,
                         queue: QueueDep) -> RaceCreated:
    """Race ready submissions on one track (students: their own against baselines and public agents)."""
    check_env_options(body.env_options)
    if len(body.submission_ids) > settings.max_race_cars:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT,
                            f"too many cars: {len(body.submission_ids)}; a race takes at most {settings.max_race_cars}")
    repeated = sorted({i for i in body.submission_ids if body.submission_ids.count(i) > 1})
    if repeated:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT,
                            f"submission {repeated[0]} is listed twice: each car races a different submission")
    entrants = [raceable(session, user, submission_id) for submission_id in body.submission_ids]
    lock_account(session, user)  # checking the quotas and creating the race: one step
    if user.role == STUDENT:
        check_friendly_race(session, user, entrants, settings.race_quota_per_day)
        check_jobs_in_flight(session, user, settings.max_jobs_in_flight)
    seed = body.seed if body.seed is not None else secrets.randbelow(2**31)
    race, job = create_race(session, entrants=entrants, seed=seed, env_options=body.env_options, created_by=user,
                            course_id=user.course_id, max_attempts=settings.max_job_attempts)
    session.commit()
    queue.enqueue(job.id)
    return RaceCreated(id=race.id, status=race.status)


def raceable(session: Session, user: User, submission_id: int) -> Submission:
    """A submission `user` may put on the grid, or the 4xx that says why not."""
    submission = session.get(Submission, submission_id)
    owner = submission.owner if submission is not None else None
    visible = owner is not None and (owner.role == BASELINE or (
        owner.course_id == user.course_id and (user.role != STUDENT or owner.id == user.id or submission.public)))
    if not visible:  # one answer whether it does not exist or is not yours to see: ids tell nothing
        raise HTTPException(status.HTTP_404_NOT_FOUND,
                            f"no submission {submission_id} you may race: your own, the baselines, or another "
                            "student's agent once its owner makes it public")
    if submission.status != READY:
        raise HTTPException(status.HTTP_409_CONFLICT,
                            f"submission {submission_id} is not ready (status: {submission.status}); "
                            "only submissions that passed validation can race")
    return submission


def check_friendly_race(session: Session, user: User, entrants: list[Submission], quota: int) -> None:
    if not any(s.owner_id == user.id for s in entrants):
        raise HTTPException(status.HTTP_403_FORBIDDEN, "a friendly race needs one of your own submissions")
    used = crud.races_started_since(session, user=user, since=utcnow() - crud.QUOTA_WINDOW)
    if used >= quota:
        raise HTTPException(status.HTTP_429_TOO_MANY_REQUESTS,
                            f"race quota reached: {quota} friendly races per 24 hours; try again later")


@router.get("", response_model=RacePage)
def read_races(session: SessionDep, viewer: OptionalUser, page: PageNumber = 1, size: PageSize = 50,
               championship_id: Annotated[int | None, Query(ge=1, le=MAX_ID)] = None) -> RacePage:
    """Your course's races (visitors: the first course's), newest first, if its board visibility lets
    you see them; else (students) the races with a car of yours."""
    course = board_course(session, viewer)
    try:
        names, entrant_ids = board_names(session, viewer, course), None
    except HTTPException:
        if viewer is None or viewer.role != STUDENT or viewer.course_id != course.id:
            raise
        names = board_names(session, viewer, course, owns=True)
        entrant_ids = crud.submission_ids_of(session, owner_id=viewer.id)
    races, total = crud.races_page(session, course_id=course.id, page=page, size=size,
                                   championship_id=championship_id, entrant_ids=entrant_ids)
    owners = entrant_owners(session, races, names)
    return RacePage(items=[race_out(session, race, names, owners) for race in races], total=total)


@router.get("/{race_id}", response_model=RaceOut)
def read_race(race_id: Id, session: SessionDep, viewer: OptionalUser) -> RaceOut:
    """A race: status, entrants and, once done, its classification (as its course's board visibility
    allows; a race with a car of yours, always)."""
    race, names, owners = visible_race(session, viewer, race_id)
    return race_out(session, race, names, owners)


@router.get("/{race_id}/replay", responses={200: {"content": {"application/json": {}},
                                                   "description": "the toolkit's replay (microracer-replay v1)"}})
def read_replay(race_id: Id, request: Request, session: SessionDep, viewer: OptionalUser) -> Response:
    """The race's replay, as `league race --replay` writes it: what the race viewer plays (as the
    race's answer, by its course's board visibility)."""
    race, names, owners = visible_race(session, viewer, race_id)
    heat_of = heat_round(session, race)
    if heat_of is not None and track_sealed(heat_of):  # a replay shows the track
        raise HTTPException(status.HTTP_409_CONFLICT, f"race {race_id} is a heat of round {heat_of.number}, which is "
                            "still being raced: its replay is shown once every heat of the round is over")
    replay = session.get(RaceReplay, race.id)
    if replay is None and race.status == FAILED:
        raise HTTPException(status.HTTP_409_CONFLICT, f"race {race_id} failed, so it has no replay: {race.error}")
    if replay is None:
        raise HTTPException(status.HTTP_409_CONFLICT,
                            f"race {race_id} is {race.status}: its replay exists once it is done")
    renamed = names.replay(replay.data, race.entrants, owners)
    if renamed is not None:
        return Response(renamed, media_type="application/json")
    if "gzip" in request.headers.get("accept-encoding", ""):  # stored compressed: sent as it is
        return Response(replay.data, media_type="application/json", headers={"Content-Encoding": "gzip"})
    return StreamingResponse(gunzipped(replay.data), media_type="application/json")


def visible_race(session: Session, viewer: User | None, race_id: int) -> tuple[Race, Names, dict[int, User]]:
    """The race, how `viewer` sees its names, its entrants' owners; or the 401/403/404 that says why not."""
    race = existing_race(session, race_id)
    owners = {s.id: s.owner for s in crud.submissions_by_id(
        session, ids=[e["submission_id"] for e in race.entrants]).values()}
    owns = viewer is not None and any(owner.id == viewer.id for owner in owners.values())
    names = board_names(session, viewer, board_course(session, viewer, race.course_id), owns=owns)
    return race, names, owners


def entrant_owners(session: Session, races: list[Race], names: Names) -> dict[int, User]:
    """submission id -> owner, of the races' entrants (needed only to show public names)."""
    if names.real:
        return {}
    ids = {e["submission_id"] for race in races for e in race.entrants}
    return {s.id: s.owner for s in crud.submissions_by_id(session, ids=list(ids)).values()}


def gunzipped(data: bytes, piece_size: int = 256 * 1024) -> Iterator[bytes]:
    """gzip `data` decompressed a piece at a time: a client that takes no gzip holds no more memory
    than one that does (a replay is ~10 times its compressed size)."""
    decompressor = zlib.decompressobj(wbits=zlib.MAX_WBITS | 16)
    while not decompressor.eof:
        piece = decompressor.decompress(data, piece_size)
        data = decompressor.unconsumed_tail
        if not piece and not data:
            break
        yield piece


@router.get("/{race_id}/log", response_class=PlainTextResponse)
def read_race_log(race_id: Id, instructor: InstructorUser, session: SessionDep) -> str:
    """What the cars' sandboxes printed, car by car (instructors only: it holds every student's
    model output; a student reads their own in their submission's log)."""
    race = existing_race(session, race_id)
    if race.course_id != instructor.course_id:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "this race belongs to another course")
    if race.status not in (DONE, FAILED):
        raise HTTPException(status.HTTP_409_CONFLICT,
                            f"race {race_id} is {race.status}: its log exists once it is over")
    return race.log or ""


def existing_race(session: Session, race_id: int) -> Race:
    race = session.get(Race, race_id)
    if race is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"race {race_id} does not exist")
    return race


def heat_round(session: Session, race: Race) -> ChampionshipRound | None:
    """The championship round `race` is a heat of, if any."""
    return session.get(ChampionshipRound, race.round_id) if race.round_id else None


def race_out(session: Session, race: Race, names: Names, owners: dict[int, User]) -> RaceOut:
    championship_round = heat_round(session, race)
    sealed = championship_round is not None and track_sealed(championship_round)
    return RaceOut(id=race.id, status=race.status, error=race.error, seed=None if sealed else race.seed,
                   env_options=race.env_options,
                   versions=race.versions, created_at=race.created_at, finished_at=race.finished_at,
                   championship_id=race.championship_id,
                   round=championship_round.number if championship_round else None, heat=race.heat,
                   entrants=names.people(race.entrants, owners),
                   classification=names.people(race.classification, owners))
