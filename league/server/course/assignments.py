"""Assignments: when a student may upload, which submission counts, and the private test at their close time.

The server's clock decides (league.server.core.clock). A student's times in an assignment: uploads open
at `opens_at`; on time until their due time (their extension, else the assignment's `due_at`); late
until `late_until` when that is after it; closed after (their close time). At their close time their
final is frozen with its candidates (their uploads), decided once each candidate is validated and
evaluated on the public tracks (final_choices: the one they selected, else their best on the public
board), then evaluated on the private tracks, as a job of the queue (close_due: run at start and on
every reaper pass, so a server down at that moment catches up; after_job: as a candidate's last job
ends). The private board, seed, tracks and figures are shown once the assignment is published (by an
instructor, or by itself when every final is decided and evaluated, with `auto_publish`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import select, update
from sqlalchemy.orm import Session

from league.server.course import assignment_grades, audit, results, standings
from league.server.db import crud
from league.server.db.models import (
    DONE, FAILED, INSTRUCTOR, PENDING, PRIVATE_TRACKS, PUBLIC_TRACKS, QUEUED, READY, REJECTED, RUNNING, STUDENT,
    VALIDATING, Assignment, Course, Evaluation, StudentAssignment, Submission, User, utcnow,
)

log = logging.getLogger("league.server.course.assignments")


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
    """Each student's final submission id (None: they have none): the one decided after their close
    time; else the ready one they selected; else their best on the assignment's public board
    (standings.best_submissions). The one rule the private test, the pages, the championships and the
    grades follow; before the final is decided, what it would be now."""
    rows = crud.student_assignments(session, assignment_id=assignment.id)
    chosen: dict[int, int | None] = {}
    for user_id in user_ids:
        row = rows.get(user_id)
        if row is not None and row.final_decided_at is not None:
            chosen[user_id] = row.final_submission_id
        elif row is not None and (selected := _selected(session, row)) is not None:
            chosen[user_id] = selected
    missing = [user_id for user_id in user_ids if user_id not in chosen]
    if missing:
        best = standings.best_submissions(session, assignment)
        chosen.update({user_id: best.get(user_id) for user_id in missing})
    return chosen


def _selected(session: Session, row: StudentAssignment) -> int | None:
    """The submission the student selected, if it is ready."""
    if row.selected_submission_id is None:
        return None
    selected = session.get(Submission, row.selected_submission_id)
    return selected.id if selected is not None and selected.status == READY else None


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
#
# Two steps, so that a queue behind at the close time costs no one their final. At the close time
# the final is frozen: what it may be is fixed (the candidates: the student's uploads, none can come
# after; and their selection). It is decided once nothing about the candidates is still to come
# (each validated, or rejected, and its public evaluation of the assignment finished) by the rule of
# final_choices, and only then is it evaluated on the private tracks. A candidate rejected, or whose
# public evaluation failed, is not on the board: it drops out. Both steps are conditional updates
# (a row is frozen once, decided once), safe when several processes run them at once.


def close_due(session: Session, *, now: datetime, max_attempts: int) -> list[int]:
    """Freeze the final of every active student whose close time has passed, decide the frozen finals
    whose candidates are all evaluated and queue their private evaluations; publish the assignments
    set to publish themselves once every final is decided and evaluated. Idempotent, in the caller's
    transaction; returns the job ids to send to the queue once committed. Run at the API's start and
    on every reaper pass (after_job does the same for one student as their candidates' jobs end)."""
    jobs = []
    undecided = select(StudentAssignment.assignment_id).where(StudentAssignment.final_at.is_not(None),
                                                              StudentAssignment.final_decided_at.is_(None))
    assignments = session.scalars(select(Assignment).where(Assignment.published_at.is_(None)
                                                           | Assignment.id.in_(undecided)).order_by(Assignment.id))
    for assignment in list(assignments):
        students = crud.active_students(session, course_id=assignment.course_id)
        rows = crud.student_assignments(session, assignment_id=assignment.id)
        closing = {s.id: window(assignment, rows.get(s.id)).closes_at for s in students}
        waiting = [s.id for s in students if (rows.get(s.id) is None or rows[s.id].final_at is None)
                   and closing[s.id] is not None and closing[s.id] <= now and assignment.published_at is None]
        for user_id in waiting:
            _freeze(session, assignment, user_id, closing[user_id])
        queued = decide_finals(session, assignment, now=now, max_attempts=max_attempts)
        if waiting or queued:
            log.info("assignment %s: %d finals frozen, %d decided and queued for their private evaluation",
                     assignment.name, len(waiting), len(queued))
        jobs += queued
        publish_if_evaluated(session, assignment, now=now, students=students)
    session.flush()
    return jobs


def _freeze(session: Session, assignment: Assignment, user_id: int, closes_at: datetime) -> None:
    """Fix the student's final at their close time: their uploads to the assignment (rejected ones
    aside) are its candidates."""
    row = crud.student_assignment(session, assignment_id=assignment.id, user_id=user_id, create=True)
    candidates = list(session.scalars(select(Submission.id).where(
        Submission.owner_id == user_id, Submission.assignment_id == assignment.id,
        Submission.status.not_in((REJECTED, FAILED))).order_by(Submission.id)))
    session.execute(update(StudentAssignment)
                    .where(StudentAssignment.id == row.id, StudentAssignment.final_at.is_(None))
                    .values(final_at=closes_at, final_candidates=candidates))
    session.expire(row)


def decide_finals(session: Session, assignment: Assignment, *, now: datetime, max_attempts: int,
                  user_ids: set[int] | None = None) -> list[int]:
    """Decide the frozen, undecided finals of the assignment (of `user_ids` only, when given) that
    wait for nothing more, and queue their private evaluations; their job ids."""
    rows = sorted((row for row in crud.student_assignments(session, assignment_id=assignment.id).values()
                   if row.final_at is not None and row.final_decided_at is None
                   and (user_ids is None or row.user_id in user_ids)),
                  key=lambda row: row.user_id)  # rows locked in one order by every process: no deadlock
    if not rows:
        return []
    candidates = {row.user_id: set(row.final_candidates or ()) for row in rows}
    unsettled = _unsettled(session, assignment, set().union(*candidates.values()))
    best: dict[int, int] | None = None
    jobs = []
    for row in rows:
        choice = _selected(session, row)
        if choice is None:
            if candidates[row.user_id] & unsettled:
                continue  # a candidate is still to be validated or evaluated
            if best is None:
                best = standings.best_submissions(session, assignment, among=set().union(*candidates.values()))
            choice = best.get(row.user_id)
        job = _decide(session, assignment, row, choice, now, max_attempts)
        if job is not None:
            jobs.append(job)
    return jobs


def _unsettled(session: Session, assignment: Assignment, submission_ids: set[int]) -> set[int]:
    """Of these submissions, those still to be validated, or with a public evaluation of the assignment
    still to run: their place on the board is not known yet."""
    if not submission_ids:
        return set()
    ids = sorted(submission_ids)
    validating = session.scalars(select(Submission.id).where(Submission.id.in_(ids),
                                                             Submission.status.in_((PENDING, VALIDATING))))
    evaluating = session.scalars(select(Evaluation.submission_id).where(
        Evaluation.submission_id.in_(ids), Evaluation.assignment_id == assignment.id, Evaluation.track == PUBLIC_TRACKS,
        Evaluation.status.in_((QUEUED, RUNNING))))
    return set(validating) | set(evaluating)


def _decide(session: Session, assignment: Assignment, row: StudentAssignment, submission_id: int | None,
            now: datetime, max_attempts: int) -> int | None:
    decided = session.execute(update(StudentAssignment).where(StudentAssignment.id == row.id,
                                                              StudentAssignment.final_decided_at.is_(None))
                              .values(final_decided_at=now, final_submission_id=submission_id)).rowcount
    session.expire(row)
    if not decided or submission_id is None:
        return None  # another process decided it; or no candidate made it
    settings = assignment.private_settings()
    evaluation, job = crud.create_evaluation(
        session, submission=session.get(Submission, submission_id), assignment=assignment, settings=settings,
        result_key=results.settings_key(settings), max_attempts=max_attempts, track=PRIVATE_TRACKS)
    session.execute(update(StudentAssignment).where(StudentAssignment.id == row.id)
                    .values(final_evaluation_id=evaluation.id))
    return job.id


def after_job(session: Session, *, submission_id: int | None, max_attempts: int) -> list[int]:
    """A validation or evaluation of the submission ended (in its job's transaction): decide the final
    it is a candidate of if it was the last one waited for, and publish its assignment if that was the
    last final to evaluate (auto_publish), without waiting for the next reaper pass. The private
    evaluation job ids it queued (the reaper's pass does all this too: a pass that loses a race with
    another process's leaves it to the next)."""
    submission = session.get(Submission, submission_id) if submission_id is not None else None
    if submission is None or submission.assignment_id is None or submission.owner.role != STUDENT:
        return []
    row = crud.student_assignment(session, assignment_id=submission.assignment_id, user_id=submission.owner_id)
    if row is None or row.final_at is None:
        return []
    assignment, now = session.get(Assignment, submission.assignment_id), utcnow()
    jobs = decide_finals(session, assignment, now=now, max_attempts=max_attempts, user_ids={row.user_id})
    publish_if_evaluated(session, assignment, now=now)
    return jobs


def publish_if_evaluated(session: Session, assignment: Assignment, *, now: datetime,
                         students: list[User] | None = None) -> bool:
    """Publish the assignment if it publishes itself and every active student's final is decided and
    evaluated on the private tracks (done or failed for good)."""
    if not assignment.auto_publish or assignment.published_at is not None:
        return False
    students = crud.active_students(session, course_id=assignment.course_id) if students is None else students
    rows = crud.student_assignments(session, assignment_id=assignment.id)
    if not students or any(s.id not in rows or rows[s.id].final_decided_at is None for s in students):
        return False
    closing = [window(assignment, rows[s.id]).closes_at for s in students]
    if any(closes is None or closes > now for closes in closing):
        return False
    ids = [rows[s.id].final_evaluation_id for s in students if rows[s.id].final_evaluation_id]
    statuses = session.scalars(select(Evaluation.status).where(Evaluation.id.in_(ids))) if ids else []
    if not all(status in (DONE, FAILED) for status in statuses):
        return False
    _publish(session, assignment, now)
    audit.record(session, actor=None, actor_name=audit.SERVER_ACTOR, action=audit.PUBLISH,
                 target_kind="assignment", target_id=assignment.id, course_id=assignment.course_id,
                 before={"published_at": None}, after=audit.snapshot(assignment, ["published_at"]),
                 note="auto_publish: every final decided and evaluated")
    log.info("assignment %s published (every final decided and evaluated)", assignment.name)
    return True


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
    _publish(session, assignment, now)


def _publish(session: Session, assignment: Assignment, now: datetime) -> None:
    """Publish (once: a conditional update), keeping each final's private result of that moment:
    a grade says so when its result changes afterwards (league.server.course.assignment_grades)."""
    published = session.execute(update(Assignment).where(Assignment.id == assignment.id,
                                                         Assignment.published_at.is_(None))
                                .values(published_at=now)).rowcount
    session.expire(assignment, ["published_at"])
    if not published:
        return
    rows = [row for row in crud.student_assignments(session, assignment_id=assignment.id).values()
            if row.final_submission_id is not None]
    current, _ = assignment_grades.private_results(session, assignment, [row.final_submission_id for row in rows])
    for row in rows:
        evaluation = current.get(row.final_submission_id)
        row.published_evaluation_id = evaluation.id if evaluation is not None else None
    session.flush()


def private_visible(assignment: Assignment | None, user: User) -> bool:
    """Whether the user may see the assignment's private seed, tracks and figures: its own course's
    instructors always, everyone else (another course's instructors too) once it is published."""
    return assignment is not None and (assignment.published_at is not None
                                       or (user.role == INSTRUCTOR and user.course_id == assignment.course_id))
