"""The course leaderboard: each student's best evaluated submission, and the baselines (as the
course's board visibility allows: league.server.course.privacy)."""
from __future__ import annotations

from fastapi import APIRouter, Request, Response
from fastapi.concurrency import run_in_threadpool

from league.server.api.cache import PRIVATE, PUBLIC, cached_json
from league.server.api.deps import (
    CacheDep, InstructorUser, OptionalUser, PageNumber, PageSize, SessionDep, SessionsDep, board_course, board_names,
    csv_response, user_course,
)
from league.server.api.schemas import LeaderboardPage
from league.server.course.standings import LEADERBOARD_GRADES, grade_rows, leaderboard_rows

router = APIRouter(tags=["leaderboard"])


@router.get("/leaderboard", response_model=LeaderboardPage)
async def read_leaderboard(request: Request, viewer: OptionalUser, session: SessionDep, sessions: SessionsDep,
                           cache: CacheDep, page: PageNumber = 1, size: PageSize = 50) -> Response:
    """Best first: completion rate, then mean return; with each agent's course-wide rating. Your
    course's board (visitors: the first course's), if its visibility lets you see it."""

    def check():
        course = board_course(session, viewer)
        return course.id, board_names(session, viewer, course)

    course_id, names = await run_in_threadpool(check)

    def compute() -> bytes:
        with sessions() as compute_session:
            rows = names.rows(leaderboard_rows(compute_session, course_id=course_id))
        return LeaderboardPage(items=rows[(page - 1) * size: page * size], total=len(rows)).model_dump_json().encode()

    return await cached_json(request, cache, sessions, ("leaderboard", course_id, names.real, page, size), compute,
                             PRIVATE if names.real else PUBLIC)


@router.get("/leaderboard.csv", response_class=Response, responses={200: {"content": {"text/csv": {}}}})
def read_leaderboard_csv(session: SessionDep, instructor: InstructorUser) -> Response:
    """Grades (instructors): one line per student of your course, ranked as on the leaderboard;
    students without an evaluated agent last, with empty figures."""
    course_id = user_course(session, instructor).id
    rows = grade_rows(session, leaderboard_rows(session, course_id=course_id), course_id=course_id,
                      columns=LEADERBOARD_GRADES)
    return csv_response(LEADERBOARD_GRADES, rows, "leaderboard.csv")
