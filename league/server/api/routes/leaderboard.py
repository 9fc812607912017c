"""The course leaderboard: each student's best evaluated submission, and the baselines (public)."""
from __future__ import annotations

from fastapi import APIRouter, Request, Response

from league.server.api.cache import cached_json
from league.server.api.deps import InstructorUser, PageNumber, PageSize, SessionDep, csv_response, user_course
from league.server.db import crud
from league.server.standings import LEADERBOARD_GRADES, grade_rows, leaderboard_rows
from league.server.schemas import LeaderboardPage

router = APIRouter(tags=["leaderboard"])


@router.get("/leaderboard", response_model=LeaderboardPage)
async def read_leaderboard(request: Request, page: PageNumber = 1, size: PageSize = 50) -> Response:
    """Best first: completion rate, then mean return; with each agent's course-wide rating."""

    def compute() -> bytes:
        with request.app.state.sessions() as session:
            course = crud.first_course(session)
            rows = leaderboard_rows(session, course_id=course.id if course else None)
        return LeaderboardPage(items=rows[(page - 1) * size: page * size], total=len(rows)).model_dump_json().encode()

    return await cached_json(request, ("leaderboard", page, size), compute)


@router.get("/leaderboard.csv", response_class=Response, responses={200: {"content": {"text/csv": {}}}})
def read_leaderboard_csv(session: SessionDep, instructor: InstructorUser) -> Response:
    """Grades (instructors): one line per student of your course, ranked as on the leaderboard;
    students without an evaluated agent last, with empty figures."""
    course_id = user_course(session, instructor).id
    rows = grade_rows(session, leaderboard_rows(session, course_id=course_id), course_id=course_id,
                      columns=LEADERBOARD_GRADES)
    return csv_response(LEADERBOARD_GRADES, rows, "leaderboard.csv")
