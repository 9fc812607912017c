"""Several courses on one server: each has its instructors, students, assignments, boards and results.

An instructor manages their own course only (every instructor route looks at `user.course_id`).
The bundled baselines (the `baselines` account, of no course) are a reference in every course:
each course evaluates them on its own assignments, and those evaluations, their jobs and their
episodes are that course's (crud.course_jobs, crud.leaderboard_entries, the submissions routes):
another course's instructors never see its private results before it publishes, nor cancel or
re-run them.
"""
from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from league.server.core.config import Settings
from league.server.course.accounts import clean_name
from league.server.course.results import change_settings
from league.server.db import crud
from league.server.db.models import INSTRUCTOR, STUDENT, Course, Job, User


class CourseRefused(ValueError):
    """A course name that is invalid, taken or unknown (the message says which)."""


def add_course(session: Session, *, name: str, settings: Settings) -> tuple[Course, list[Job]]:
    """A new course with its default assignment (the server's default evaluation settings and board
    visibility), and the evaluations of the baselines on it, queued in the caller's transaction (send
    the jobs to the queue once committed)."""
    try:
        name = clean_name(name)
    except ValueError as error:
        raise CourseRefused(str(error).replace("the name", "the course name", 1)) from None
    if course_named(session, name) is not None:
        raise CourseRefused(f"a course named {name!r} exists already")
    course = crud.get_or_create_course(session, name=name, evaluation=settings.default_evaluation(),
                                       board_visibility=settings.board_visibility)
    assignment = crud.default_assignment(session, course_id=course.id)
    change = change_settings(session, assignment=assignment, settings=assignment.evaluation_settings(),
                             max_attempts=settings.max_job_attempts, unchanged="")
    return course, change.queued


def course_named(session: Session, name: str) -> Course | None:
    return session.scalar(select(Course).where(Course.name == name))


def existing_course(session: Session, name: str | None) -> Course:
    """The course named `name` (None: the first one, the server's default course)."""
    course = crud.first_course(session) if name is None else course_named(session, name)
    if course is None:
        known = ", ".join(session.scalars(select(Course.name).order_by(Course.id))) or "none"
        raise CourseRefused(f"no course {name!r} (courses: {known}; `league courses add NAME` creates one)")
    return course


def course_counts(session: Session) -> list[tuple[Course, int, int]]:
    """Every course, oldest first, with how many active instructors and students it has."""
    counted = {}
    for course_id, role, count in session.execute(
            select(User.course_id, User.role, func.count(User.id)).where(User.revoked_at.is_(None))
            .group_by(User.course_id, User.role)):
        counted[course_id, role] = count
    return [(course, counted.get((course.id, INSTRUCTOR), 0), counted.get((course.id, STUDENT), 0))
            for course in session.scalars(select(Course).order_by(Course.id))]
