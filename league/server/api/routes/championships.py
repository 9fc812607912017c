"""Championships: instructors create them and run rounds; their standings are shown as the course's
board visibility allows (league.server.course.privacy)."""
from __future__ import annotations

import secrets

from fastapi import APIRouter, HTTPException, Request, Response, status
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from league.server.api.cache import PRIVATE, PUBLIC, cached_json
from league.server.course import audit
from league.server.api.deps import (
    CacheDep, Id, InstructorUser, OptionalUser, PageNumber, PageSize, QueueDep, SessionDep, SessionsDep, SettingsDep,
    board_course, board_names, check_env_options, csv_response, user_course,
)
from league.server.api.schemas import ChampionshipCreate, ChampionshipOut, RoundOut, StandingsPage
from league.server.course.privacy import Names
from league.server.course.races import RoundRefused, retry_round, round_summary, start_round
from league.server.course.standings import STANDINGS_GRADES, grade_rows, standings_rows
from league.server.db import crud
from league.server.db.models import Assignment, Championship, ChampionshipRound, User

router = APIRouter(prefix="/championships", tags=["championships"])


@router.post("", response_model=ChampionshipOut, status_code=status.HTTP_201_CREATED)
def create_championship(body: ChampionshipCreate, instructor: InstructorUser, session: SessionDep,
                        settings: SettingsDep) -> ChampionshipOut:
    """A new championship of your course (its rounds are run with POST .../rounds)."""
    check_env_options(body.env_options)
    if body.heat_size > settings.max_race_cars:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT,
                            f"heat_size {body.heat_size} is too large: "
                            f"a race takes at most {settings.max_race_cars} cars")
    if any(p < 0 for p in body.points):
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "points must not be negative")
    course = user_course(session, instructor)
    assignment = session.get(Assignment, body.assignment) if body.assignment is not None else None
    if body.assignment is not None and (assignment is None or assignment.course_id != course.id):
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no assignment {body.assignment} in your course")
    championship = Championship(course_id=course.id, assignment_id=body.assignment, name=body.name.strip(),
                                env_options=body.env_options, heat_size=body.heat_size, points=body.points,
                                include_baselines=body.include_baselines, created_by_id=instructor.id,
                                seed=body.seed if body.seed is not None else secrets.randbelow(2**31))
    session.add(championship)
    session.flush()
    audit.record(session, actor=instructor, action=audit.CREATE_CHAMPIONSHIP, target_kind="championship",
                 target_id=championship.id, course_id=championship.course_id, name=championship.name)
    session.commit()
    return championship_out(championship)


@router.get("", response_model=list[ChampionshipOut])
def read_championships(session: SessionDep, viewer: OptionalUser) -> list[ChampionshipOut]:
    """Your course's championships (visitors: the first course's), oldest first, if its board
    visibility lets you see them."""
    course = board_course(session, viewer)
    board_names(session, viewer, course)
    return [championship_out(c) for c in crud.course_championships(session, course_id=course.id)]


@router.get("/{championship_id}", response_model=ChampionshipOut)
def read_championship(championship_id: Id, session: SessionDep, viewer: OptionalUser) -> ChampionshipOut:
    """A championship and its rounds (by its course's board visibility)."""
    return championship_out(visible_championship(session, viewer, championship_id)[0])


@router.post("/{championship_id}/rounds", response_model=RoundOut, status_code=status.HTTP_202_ACCEPTED)
def create_round(championship_id: Id, instructor: InstructorUser, session: SessionDep, settings: SettingsDep,
                 queue: QueueDep) -> RoundOut:
    """Run the next round: every student's active submission, in heats on a new track."""
    championship = existing_championship(session, championship_id)
    if championship.course_id != user_course(session, instructor).id:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "this championship belongs to another course")
    try:
        championship_round, job_ids = start_round(session, championship=championship, created_by=instructor,
                                                  max_attempts=settings.max_job_attempts)
        audit.record(session, actor=instructor, action=audit.RUN_ROUND, target_kind="championship",
                     target_id=championship.id, course_id=championship.course_id, round=championship_round.number,
                     heats=len(job_ids))
        session.commit()
    except RoundRefused as refusal:
        raise HTTPException(status.HTTP_409_CONFLICT, str(refusal)) from refusal
    except IntegrityError as error:  # two instructors clicked at once: the other round was created
        raise HTTPException(status.HTTP_409_CONFLICT, "another round of this championship was just started") from error
    for job_id in job_ids:
        queue.enqueue(job_id)
    return RoundOut(**round_summary(championship_round))


@router.get("/{championship_id}/rounds/{number}", response_model=RoundOut)
def read_round(championship_id: Id, number: Id, session: SessionDep, viewer: OptionalUser) -> RoundOut:
    """A round's progress: heats done out of the total, and its races (by its course's board visibility)."""
    visible_championship(session, viewer, championship_id)
    return RoundOut(**round_summary(existing_round(session, championship_id, number)))


@router.post("/{championship_id}/rounds/{number}/retry", response_model=RoundOut,
             status_code=status.HTTP_202_ACCEPTED)
def retry_failed_round(championship_id: Id, number: Id, instructor: InstructorUser, session: SessionDep,
                       settings: SettingsDep, queue: QueueDep) -> RoundOut:
    """Race the failed heats of the latest round again (e.g. after its workers failed for good)."""
    championship = existing_championship(session, championship_id)
    if championship.course_id != user_course(session, instructor).id:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "this championship belongs to another course")
    championship_round = existing_round(session, championship_id, number)
    try:
        job_ids = retry_round(session, championship=championship, championship_round=championship_round,
                              max_attempts=settings.max_job_attempts)
        audit.record(session, actor=instructor, action=audit.RETRY_ROUND, target_kind="championship",
                     target_id=championship.id, course_id=championship.course_id, round=championship_round.number,
                     heats=len(job_ids))
        session.commit()
    except RoundRefused as refusal:
        raise HTTPException(status.HTTP_409_CONFLICT, str(refusal)) from refusal
    for job_id in job_ids:
        queue.enqueue(job_id)
    return RoundOut(**round_summary(championship_round))


def existing_round(session: SessionDep, championship_id: int, number: int) -> ChampionshipRound:
    championship_round = crud.championship_round(session, championship_id=championship_id, number=number)
    if championship_round is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"championship {championship_id} has no round {number}")
    return championship_round


@router.get("/{championship_id}/standings", response_model=StandingsPage)
async def read_standings(championship_id: Id, request: Request, session: SessionDep, sessions: SessionsDep,
                         cache: CacheDep, viewer: OptionalUser, page: PageNumber = 1, size: PageSize = 50) -> Response:
    """Points (ties: wins, then best finishes) and OpenSkill ratings after the finished rounds (by its
    course's board visibility)."""
    _, names = await run_in_threadpool(visible_championship, session, viewer, championship_id)

    def compute() -> bytes:
        with sessions() as compute_session:
            rows = names.rows(standings_rows(compute_session, existing_championship(compute_session, championship_id)))
        return StandingsPage(items=rows[(page - 1) * size: page * size], total=len(rows)).model_dump_json().encode()

    return await cached_json(request, cache, sessions, ("standings", championship_id, names.real, page, size), compute,
                             PRIVATE if names.real else PUBLIC)


@router.get("/{championship_id}/standings.csv", response_class=Response, responses={200: {"content": {"text/csv": {}}}})
def read_standings_csv(championship_id: Id, session: SessionDep, instructor: InstructorUser) -> Response:
    """Grades (instructors of the championship's course): the standings' lines of your students,
    then the students who raced in no finished round, with empty figures."""
    championship = existing_championship(session, championship_id)
    if championship.course_id != user_course(session, instructor).id:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "this championship is another course's")
    rows = grade_rows(session, standings_rows(session, championship), course_id=championship.course_id,
                      columns=STANDINGS_GRADES)
    return csv_response(STANDINGS_GRADES, rows, f"standings-{championship_id}.csv")


def visible_championship(session: Session, viewer: User | None, championship_id: int) -> tuple[Championship, Names]:
    """The championship and how `viewer` sees its names; or the 401/403/404 that says why not."""
    championship = existing_championship(session, championship_id)
    return championship, board_names(session, viewer, board_course(session, viewer, championship.course_id))


def existing_championship(session: Session, championship_id: int) -> Championship:
    championship = session.get(Championship, championship_id)
    if championship is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"championship {championship_id} does not exist")
    return championship


def championship_out(championship: Championship) -> ChampionshipOut:
    return ChampionshipOut(id=championship.id, name=championship.name, env_options=championship.env_options,
                           heat_size=championship.heat_size, points=championship.points,
                           include_baselines=championship.include_baselines, seed=championship.seed,
                           assignment_id=championship.assignment_id,
                           created_at=championship.created_at,
                           rounds=[round_summary(r) for r in championship.rounds])
