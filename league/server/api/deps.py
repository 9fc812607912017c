"""What the routes share: dependencies as Annotated aliases, paging parameters, and checks that
several resources make (a user's course, environment options)."""
from __future__ import annotations

from collections.abc import AsyncIterator, Iterable
from typing import Annotated

from fastapi import Depends, HTTPException, Path, Query, Request, Response, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session, sessionmaker

import league
from league.spreadsheet import csv_text
from league.server.api.cache import ResponseCache
from league.server.api.watch import ProcessWatch
from league.server.core.clock import Clock
from league.server.core.config import Settings
from league.server.course.privacy import AUDIENCE, Names
from league.server.db import crud
from league.server.db.models import INSTRUCTOR, VISIBILITY_INSTRUCTORS, VISIBILITY_PUBLIC, STUDENT, Course, User
from league.server.jobs.queue import JobQueue
from league.server.services import Services
from league.server.storage import BlobStore

MAX_ID = 2**63 - 1  # ids are 64-bit integers in the database: a larger number names nothing
bearer = HTTPBearer(auto_error=False, description="the API token printed by `league users add` or the roster")


# Every route reaches the league's services through these (create_app keeps them as app.state.services
# and the public answers' cache as app.state.cache). The cheap ones are `async def`: FastAPI runs them
# in the event loop instead of handing each one to the thread pool (a hop that costs more than the
# work under load).


async def get_services(request: Request) -> Services:
    return request.app.state.services


ServicesDep = Annotated[Services, Depends(get_services)]


async def get_settings(services: ServicesDep) -> Settings:
    return services.settings


async def get_sessions(services: ServicesDep) -> sessionmaker[Session]:
    """The sessionmaker, for work that opens sessions of its own (in a thread, or one per step)."""
    return services.sessions


async def get_session(services: ServicesDep) -> AsyncIterator[Session]:
    """A session per request; opening one does no I/O (the first query, in the handler's thread, does)."""
    with services.sessions() as session:
        yield session


async def get_clock(services: ServicesDep) -> Clock:
    return services.clock


async def get_queue(services: ServicesDep) -> JobQueue:
    return services.queue


async def get_store(services: ServicesDep) -> BlobStore:
    return services.store


async def get_cache(request: Request) -> ResponseCache:
    return request.app.state.cache


SettingsDep = Annotated[Settings, Depends(get_settings)]
SessionsDep = Annotated[sessionmaker[Session], Depends(get_sessions)]
SessionDep = Annotated[Session, Depends(get_session)]
ClockDep = Annotated[Clock, Depends(get_clock)]
QueueDep = Annotated[JobQueue, Depends(get_queue)]
StoreDep = Annotated[BlobStore, Depends(get_store)]
CacheDep = Annotated[ResponseCache, Depends(get_cache)]


async def get_watch(request: Request) -> ProcessWatch:
    """This API process's watch (league.server.api.watch): its row in the workers table, the schema under it."""
    return request.app.state.watch


WatchDep = Annotated[ProcessWatch, Depends(get_watch)]


UNKNOWN_TOKEN = "unknown token (replaced by a new one, or mistyped): ask your instructor for your current token"


def unauthorized(detail: str) -> HTTPException:
    return HTTPException(status.HTTP_401_UNAUTHORIZED, detail, headers={"WWW-Authenticate": "Bearer"})


def get_current_user(request: Request, session: SessionDep,
                     credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> User:
    if credentials is None:
        raise unauthorized("missing token: send the header Authorization: Bearer TOKEN")
    user = crud.user_by_token(session, token=credentials.credentials)
    if user is None:  # no user has it (any more): a new token replaces the old one
        raise unauthorized(UNKNOWN_TOKEN)
    if not user.active:
        raise unauthorized("this account was revoked")
    request.state.user_id = user.id  # for the access log (league.server.core.logs.log_access)
    # End the lookup's transaction: its connection goes back to the pool. A route that opens a
    # session of its own (an upload) would otherwise hold two at once, and a burst of such requests
    # can take the whole pool and wait on itself until the pool's timeout.
    session.commit()
    return user


CurrentUser = Annotated[User, Depends(get_current_user)]


def get_optional_user(request: Request, session: SessionDep,
                      credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> User | None:
    """The user of the token, or None without one (a token sent is checked: a refused one is a 401)."""
    return None if credentials is None else get_current_user(request, session, credentials)


OptionalUser = Annotated[User | None, Depends(get_optional_user)]


async def get_instructor(user: CurrentUser) -> User:
    if user.role != INSTRUCTOR:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only instructors may do this")
    return user


InstructorUser = Annotated[User, Depends(get_instructor)]


Id = Annotated[int, Path(ge=1, le=MAX_ID, description="an id (a 64-bit integer)")]
MAX_PAGE = 100_000  # a bound on the database's offsets (and on the keys of cached pages)
PageNumber = Annotated[int, Query(ge=1, le=MAX_PAGE, description="1-based")]
PageSize = Annotated[int, Query(ge=1, le=100)]


def user_course(session: Session, user: User) -> Course:
    """The user's course (the baselines' account has none: the first course)."""
    course = user.course or crud.first_course(session)
    if course is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no course yet")
    return course


def board_course(session: Session, viewer: User | None, course_id: int | None = None) -> Course:
    """The course whose board is asked for: `course_id`'s (a race's, a championship's), else the
    viewer's, else (a visitor) the first course."""
    course = session.get(Course, course_id) if course_id is not None else None
    if course is None and viewer is not None and viewer.course_id is not None:
        course = session.get(Course, viewer.course_id)
    course = course or crud.first_course(session)
    if course is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no course yet")
    return course


def board_names(session: Session, viewer: User | None, course: Course, *, owns: bool = False) -> Names:
    """The check of every route that shows students' names or results (the course's board
    visibility, league.server.course.privacy): how `viewer` (None: not logged in) sees the course's
    boards, or a 401 (log in) / 403 (who may see them). Its instructors, and its students unless
    the board is for instructors only, see real names; visitors of a public board, and a student
    who `owns` what is shown (a race with their car), see public names."""
    visibility = course.board_visibility
    member = viewer is not None and viewer.course_id == course.id and viewer.role in (STUDENT, INSTRUCTOR)
    if member and (viewer.role == INSTRUCTOR or visibility != VISIBILITY_INSTRUCTORS):
        return Names(real=True)
    if visibility == VISIBILITY_PUBLIC or owns:
        return Names(real=False, viewer_id=viewer.id if viewer else None,
                     display_names=crud.display_names(session, course_id=course.id),
                     pseudonyms=crud.pseudonyms(session, course_id=course.id))
    audience = f"the boards of course {course.name!r} are shown to {AUDIENCE[visibility]}"
    if viewer is None:
        raise unauthorized(f"log in to see this: {audience} (your token is from your instructor)")
    raise HTTPException(status.HTTP_403_FORBIDDEN, f"{audience}; you are {viewer.name!r} ({viewer.role}"
                                                   f"{'' if member else ' of another course'})")


def check_env_options(options: dict) -> None:
    """Options of an evaluation, a race or a championship, as the simulator accepts them (422 if not)."""
    if "observation" in options:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT,
                            "observation is not an evaluation setting: it follows each agent's input size")
    try:
        league.RaceOptions.from_kwargs(**options)
    except (TypeError, ValueError) as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"invalid env_options: {error}") from error


def lock_account(session: Session, user: User) -> None:
    """Hold the user's row for this transaction (crud.lock_user); 401 if the account was deleted
    since its token was checked."""
    if not crud.lock_user(session, user_id=user.id):
        raise unauthorized("this account was deleted")


def check_upload_quota(session: Session, user: User, limit: int) -> None:
    usage = crud.quota_usage(session, owner=user, limit=limit)
    if usage.exhausted:
        raise HTTPException(status.HTTP_429_TOO_MANY_REQUESTS,
                            f"quota reached: {limit} submissions per 24 hours (rejected ones do not count); "
                            f"next free slot at {usage.next_free_at.isoformat(timespec='seconds')}")


def check_jobs_in_flight(session: Session, user: User, limit: int) -> None:
    waiting = crud.jobs_in_flight(session, owner_id=user.id)
    if waiting >= limit:
        raise HTTPException(status.HTTP_429_TOO_MANY_REQUESTS,
                            f"{waiting} of your uploads or races are still waiting or running (at most {limit} at "
                            "once): upload again when one of them is done")


def csv_response(header: list[str], rows: Iterable[list], filename: str) -> Response:
    """A CSV download that no spreadsheet runs as formulas (league.spreadsheet: text cells quoted
    and neutralised, numbers left as they are)."""
    return Response(csv_text(header, rows), media_type="text/csv; charset=utf-8",
                    headers={"Content-Disposition": f'attachment; filename="{filename}"'})
