"""Assignments: when a student may upload, which submission counts, and the private test at their close time.

The server's clock decides (league.server.clock). A student's times in an assignment: uploads open
at `opens_at`; on time until their due time (their extension, else the assignment's `due_at`); late
until `late_until` when that is after it; closed after (their close time). At their close time their
final submission (final_choices: the one they selected, else their best on the public board) is
frozen and evaluated on the private tracks, as a job of the queue (close_due: run at start and on
every reaper pass, so a server down at that moment catches up). The private board, seed, tracks and
figures are shown once the assignment is published (by an instructor, or by itself when every
final is evaluated, with `auto_publish`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import select, update
from sqlalchemy.orm import Session

from league.server import results
from league.server.db import crud
from league.server.db.models import (
    DONE, FAILED, PRIVATE, READY, STUDENT, Assignment, Course, Evaluation, StudentAssignment, Submission, User,
)

log = logging.getLogger("league.server.assignments")


class UploadRefused(Exception):
    """An upload the assignment's rules refuse; `status` the HTTP status, the message says why and when."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


def iso(moment: datetime | None) -> str | None:
    """A UTC time as the API shows it: 2026-12-01T23:59:00+00:00."""
    return None if moment is None else moment.isoformat(timespec="seconds")


@dataclass(frozen=True)
class Window:
    """A student's times in an assignment (None: no such time)."""

    opens_at: datetime | None
    due_at: datetime | None  # their own: an extension replaces the assignment's
    late_until: datetime | None  # only when after their due time
    extended: bool
    retired: bool = False  # the automatic assignment, replaced by the instructors' own (`retired`)

    @property
    def closes_at(self) -> datetime | None:
        return self.late_until or self.due_at

    def state(self, now: datetime) -> str:
        """upcoming, open, late or closed."""
        if self.retired:
            return "closed"
        if self.opens_at is not None and now < self.opens_at:
            return "upcoming"
        if self.due_at is None or now < self.due_at:
            return "open"
        return "late" if self.late_until is not None and now < self.late_until else "closed"


def window(assignment: Assignment, row: StudentAssignment | None, retired: bool = False) -> Window:
    """A student's times (`row`: their row of the assignment); `retired`: what `retired` says of it."""
    extension = row.extension_due_at if row is not None else None
    due = extension or assignment.due_at
    late = assignment.late_until if due is not None and assignment.late_until and assignment.late_until > due else None
    return Window(assignment.opens_at, due, late, extension is not None, retired)


def retired(session: Session, assignment: Assignment) -> bool:
    """Whether the course's automatic assignment takes no more uploads: once the course has an
    assignment of its instructors', it would take a student's `league submit` (and the web upload)
    away from theirs, unless they keep it open on purpose (`keep_open`)."""
    return assignment.automatic and not assignment.keep_open and crud.has_own_assignments(
        session, course_id=assignment.course_id)


def user_window(session: Session, assignment: Assignment, user: User) -> Window:
    """The user's times in the assignment, as uploads follow them."""
    return window(assignment, crud.student_assignment(session, assignment_id=assignment.id, user_id=user.id),
                  retired(session, assignment))


# --------------------------------------------------------------------------- uploads


def upload_assignment(session: Session, *, user: User, course: Course, wanted: str | None,
                      now: datetime) -> Assignment:
    """The assignment an upload goes to: `wanted` (an id or a name of the course), else the only one
    open to the user now (422 listing them if several, or saying when they open or closed if none)."""
    assignments = crud.course_assignments(session, course_id=course.id)
    if wanted:
        wanted = wanted.strip()
        for assignment in assignments:
            if assignment.name == wanted or (wanted.isdigit() and assignment.id == int(wanted)):
                return assignment
        raise UploadRefused(404, f"no assignment {wanted!r} in your course (see `league assignments`)")
    open_ = open_assignments(session, user=user, assignments=assignments, now=now)
    if len(open_) == 1:
        return open_[0]
    if open_:
        raise UploadRefused(422, "several assignments are open: " + ", ".join(a.name for a in open_)
                            + ": name one (the form field `assignment`, or `league submit FILE --assignment NAME`)")
    listed = "; ".join(f"{a.name}: {user_window(session, a, user).state(now)}" for a in assignments) \
        or "the course has none"
    raise UploadRefused(422, f"no assignment is open for uploads ({listed})")


def open_assignments(session: Session, *, user: User, assignments: list[Assignment], now: datetime) -> list[Assignment]:
    """Those of `assignments` that take the user's uploads now (on time or late)."""
    return [a for a in assignments if user_window(session, a, user).state(now) in ("open", "late")]


def check_upload(session: Session, *, assignment: Assignment, user: User, now: datetime) -> bool:
    """Refuse a student's upload outside their window or over the daily quota (UploadRefused); True
    if it is late. Instructors' uploads are never refused nor late."""
    if user.role != STUDENT:
        return False
    times = user_window(session, assignment, user)
    if times.retired:
        own = [a.name for a in crud.course_assignments(session, course_id=assignment.course_id) if not a.automatic]
        raise UploadRefused(403, f"{assignment.name} takes no more uploads: the course's assignments are "
                                 f"{', '.join(own)} (`league submit FILE --assignment NAME`)")
    state = times.state(now)
    if state == "upcoming":
        raise UploadRefused(403, f"{assignment.name} opens for uploads at {iso(times.opens_at)}")
    if state == "closed":
        raise UploadRefused(403, f"{assignment.name} closed for your uploads at {iso(times.closes_at)}")
    if assignment.daily_quota:
        day = now.replace(hour=0, minute=0, second=0, microsecond=0)
        used = crud.uploads_since(session, owner_id=user.id, assignment_id=assignment.id, since=day)
        if used >= assignment.daily_quota:
            raise UploadRefused(429, f"quota of {assignment.name} reached: {assignment.daily_quota} uploads per "
                                     f"UTC day (rejected ones do not count); it resets at "
                                     f"{iso(day + timedelta(days=1))}")
    return state == "late"


# --------------------------------------------------------------------------- final submissions


def final_choices(session: Session, assignment: Assignment, user_ids: list[int]) -> dict[int, int | None]:
    """Each student's final submission id (None: they have none): the one frozen at their close time;
    else the ready one they selected; else their best on the assignment's public board (its best
    ranked row, else its stale row). The one rule the private test, the pages and the grades follow."""
    rows = crud.student_assignments(session, assignment_id=assignment.id)
    chosen: dict[int, int | None] = {}
    for user_id in user_ids:
        row = rows.get(user_id)
        if row is not None and row.final_at is not None:
            chosen[user_id] = row.final_submission_id
        elif row is not None and row.selected_submission_id is not None:
            selected = session.get(Submission, row.selected_submission_id)
            if selected is not None and selected.status == READY:
                chosen[user_id] = selected.id
    missing = [user_id for user_id in user_ids if user_id not in chosen]
    if missing:
        from league.server.standings import assignment_board  # (standings reads results, which reads this)
        best = {}
        for row in reversed(assignment_board(session, assignment)):  # the best last: it wins
            best[row["owner_id"]] = row["submission_id"]
        chosen.update({user_id: best.get(user_id) for user_id in missing})
    return chosen


def select_final(session: Session, *, assignment: Assignment, user: User, submission_id: int | None,
                 now: datetime) -> None:
    """Select the user's final submission (None: back to their best); refused after their close time."""
    row = crud.student_assignment(session, assignment_id=assignment.id, user_id=user.id, create=True)
    closes = window(assignment, row).closes_at
    if row.final_at is not None or (closes is not None and now >= closes):
        raise UploadRefused(409, f"your final submission of {assignment.name} was frozen at {iso(closes)}")
    if submission_id is not None:
        submission = crud.ready_submission_of(session, owner_id=user.id, submission_id=submission_id)
        if submission is None or submission.assignment_id != assignment.id:
            raise UploadRefused(404, f"no ready submission {submission_id} of yours in {assignment.name}")
    row.selected_submission_id = submission_id
    session.flush()


# --------------------------------------------------------------------------- the private test


def close_due(session: Session, *, now: datetime, max_attempts: int) -> list[int]:
    """Freeze the final of every active student whose close time has passed and queue its private
    evaluation; publish the assignments set to publish themselves once every final is evaluated.
    Idempotent (a final is frozen once: a conditional update), in the caller's transaction; returns
    the job ids to send to the queue once committed."""
    jobs = []
    unpublished = session.scalars(select(Assignment).where(Assignment.published_at.is_(None)).order_by(Assignment.id))
    for assignment in list(unpublished):
        students = crud.active_students(session, course_id=assignment.course_id)
        rows = crud.student_assignments(session, assignment_id=assignment.id)
        closing = {s.id: window(assignment, rows.get(s.id)).closes_at for s in students}
        waiting = [s.id for s in students if (rows.get(s.id) is None or rows[s.id].final_at is None)
                   and closing[s.id] is not None and closing[s.id] <= now]
        if waiting:
            choices = final_choices(session, assignment, waiting)
            for user_id in waiting:
                job = _freeze(session, assignment, user_id, closing[user_id], choices[user_id], max_attempts)
                if job is not None:
                    jobs.append(job)
            log.info("assignment %s: %d finals frozen, %d private evaluations queued", assignment.name,
                     len(waiting), len(jobs))
        if assignment.auto_publish and _all_finals_evaluated(session, assignment, students, closing, now):
            assignment.published_at = now
            log.info("assignment %s published (every final evaluated)", assignment.name)
    session.flush()
    return jobs


def _freeze(session: Session, assignment: Assignment, user_id: int, closes_at: datetime, submission_id: int | None,
            max_attempts: int) -> int | None:
    row = crud.student_assignment(session, assignment_id=assignment.id, user_id=user_id, create=True)
    frozen = session.execute(update(StudentAssignment).where(StudentAssignment.id == row.id,
                                                             StudentAssignment.final_at.is_(None))
                             .values(final_at=closes_at, final_submission_id=submission_id)).rowcount
    if not frozen or submission_id is None:
        return None  # another process froze it; or nothing to evaluate
    settings = assignment.private_settings()
    evaluation, job = crud.create_evaluation(
        session, submission=session.get(Submission, submission_id), assignment=assignment, settings=settings,
        result_key=results.settings_key(settings), max_attempts=max_attempts, track=PRIVATE)
    session.execute(update(StudentAssignment).where(StudentAssignment.id == row.id)
                    .values(final_evaluation_id=evaluation.id))
    session.expire(row)
    return job.id


def _all_finals_evaluated(session: Session, assignment: Assignment, students: list[User],
                          closing: dict[int, datetime | None], now: datetime) -> bool:
    if any(closes is None or closes > now for closes in closing.values()) or not students:
        return False
    rows = crud.student_assignments(session, assignment_id=assignment.id)
    ids = [rows[s.id].final_evaluation_id for s in students if s.id in rows and rows[s.id].final_evaluation_id]
    if len(rows) < len(students) or any(rows[s.id].final_at is None for s in students):
        return False
    statuses = session.scalars(select(Evaluation.status).where(Evaluation.id.in_(ids))) if ids else []
    return all(status in (DONE, FAILED) for status in statuses)


def publish(session: Session, *, assignment: Assignment, now: datetime) -> None:
    """Show the private board, seed and tracks; refused while some student may still upload."""
    if assignment.published_at is not None:
        return
    students = crud.active_students(session, course_id=assignment.course_id)
    rows = crud.student_assignments(session, assignment_id=assignment.id)
    closing = {s.name: window(assignment, rows.get(s.id)).closes_at for s in students}
    still = [name for name, closes in closing.items() if closes is None or closes > now]
    if still:
        shown = ", ".join(still[:5]) + (f" and {len(still) - 5} more" if len(still) > 5 else "")
        raise UploadRefused(409, f"{assignment.name} cannot be published while students may still upload "
                                 f"(no due time, or not passed yet): {shown}")
    assignment.published_at = now
    session.flush()


def private_visible(assignment: Assignment | None, user: User) -> bool:
    """Whether the user may see the assignment's private seed, tracks and figures: instructors always,
    everyone else once it is published."""
    return assignment is not None and (user.role != STUDENT or assignment.published_at is not None)
