"""An assignment's grades from the database: each student's frozen final and its private result, read
here and graded by league.server.course.grading (which holds every rule and touches no database).

Only private results of the assignment's **current** private settings count (league.server.course.results'
key): after a change of its settings a final evaluated with the old ones is `stale`, with an empty
grade, until it is evaluated again; grades never mix results of two settings. Setting the rubric
queues, at LOW priority, the private evaluations the grades lack (`queue_missing_evaluations`): the
baselines' (their reference lines) and, after a change of the settings, the stale finals'.
"""
from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from league.server.course import grading, results
from league.server.db import crud
from league.server.db.models import (
    DONE, LOW, PRIVATE_TRACKS, QUEUED, RUNNING, STUDENT, Assignment, Evaluation, Job, StudentAssignment, Submission,
    User,
)


class NoRubric(LookupError):
    """The assignment has no rubric yet."""


def rubric_of(assignment: Assignment) -> grading.PointsRubric | grading.FormulaRubric:
    if assignment.rubric is None:
        raise NoRubric(f"{assignment.name} has no rubric yet: set one (PUT /api/assignments/{assignment.id}/rubric)")
    return grading.read_rubric(assignment.rubric)


def private_key(assignment: Assignment) -> str:
    return results.settings_key(assignment.private_settings())


def private_results(session: Session, assignment: Assignment,
                    submission_ids: list[int]) -> tuple[dict[int, Evaluation], set[int]]:
    """Each submission's newest finished private evaluation of the current private settings; and the
    submissions that have such evaluations of other settings only (stale)."""
    key, current, other = private_key(assignment), {}, set()
    if not submission_ids:
        return current, other
    for evaluation in session.scalars(select(Evaluation).where(
            Evaluation.assignment_id == assignment.id, Evaluation.track == PRIVATE_TRACKS, Evaluation.status == DONE,
            Evaluation.submission_id.in_(submission_ids)).order_by(Evaluation.id)):
        if evaluation.result_key == key:
            current[evaluation.submission_id] = evaluation  # ordered by id: the newest wins
        else:
            other.add(evaluation.submission_id)
    return current, other - set(current)


def figures(evaluation: Evaluation | None) -> dict:
    if evaluation is None:
        return {}
    return {"completed": evaluation.completed / max(evaluation.episodes_total or 0, 1),
            "mean_return": evaluation.mean_return, "mean_speed": evaluation.mean_speed}


def assignment_entries(session: Session, assignment: Assignment) -> list[grading.Entry]:
    """Every student of the course (revoked ones flagged) with their final, and the baselines with a
    private result, as league.server.course.grading reads them."""
    students = [u for u in crud.course_users(session, course_id=assignment.course_id) if u.role == STUDENT]
    rows = crud.student_assignments(session, assignment_id=assignment.id)
    frozen = {u.id: rows[u.id] for u in students if u.id in rows and rows[u.id].final_at}
    baselines = crud.ready_baseline_submissions(session)
    finals = crud.submissions_by_id(session, ids=[row.final_submission_id for row in frozen.values()
                                                  if row.final_submission_id is not None])
    current, stale = private_results(session, assignment, list(finals) + [b.id for b in baselines])
    published = assignment.published_at is not None
    entries = [_student_entry(session, u, frozen.get(u.id), finals, current, stale, published) for u in students]
    entries += [grading.Entry(name=b.name, baseline=True, submission_id=b.id, **figures(current[b.id]))
                for b in baselines if b.id in current]
    return entries


def _student_entry(session: Session, user: User, row: StudentAssignment | None, finals: dict[int, Submission],
                   current: dict[int, Evaluation], stale: set[int], published: bool) -> grading.Entry:
    # a student revoked before their close time is never frozen (close_due takes active students):
    # they have no final
    closed = row is not None or user.revoked_at is not None
    final = finals.get(row.final_submission_id) if row is not None else None
    evaluation = current.get(final.id) if final else None
    return grading.Entry(name=user.name, user_id=user.id, email=user.email, student_id=user.student_id,
                        canvas_id=user.canvas_id, sis_login_id=user.sis_login_id,
                        revoked=user.revoked_at is not None, closed=closed,
                        deciding=row is not None and row.final_decided_at is None,
                        submission_id=final.id if final else None, late=bool(final and final.late),
                        stale=bool(final and final.id in stale), **figures(evaluation),
                        note=revision(session, row, evaluation) if published else None)


def revision(session: Session, row: StudentAssignment | None, evaluation: Evaluation | None) -> str | None:
    """How a published assignment's grade changed since its publication (None: it did not): its
    final's private result then (league.server.course.assignments keeps its id) against the one that counts now."""
    then = row.published_evaluation_id if row is not None else None
    now = evaluation.id if evaluation is not None else None
    if then == now:
        return None
    if then is None:
        return "graded after the publication (its private evaluation finished after it)"
    before = session.get(Evaluation, then)
    was = (f": completed {before.completed}/{before.episodes_total}, mean return {before.mean_return:.3f} at the "
           f"publication" if before is not None and before.status == DONE else "")
    if now is None:
        return f"its private result at the publication no longer counts (settings changed){was}"
    return f"re-evaluated after the publication{was}"


def assignment_grades(session: Session, assignment: Assignment) -> list[grading.GradeRow]:
    """The assignment's rows (NoRubric without a rubric; grading.FormulaError if its formula has no
    value for some student's figures)."""
    return grading.grade(assignment_entries(session, assignment), rubric_of(assignment),
                        late_penalty=assignment.late_penalty)


def queue_missing_evaluations(session: Session, *, assignment: Assignment, max_attempts: int) -> list[Job]:
    """A private evaluation, at LOW priority, of each ready baseline and each frozen final without one
    of the current private settings (done, running or queued). In the caller's transaction."""
    key = private_key(assignment)
    covered = set(session.scalars(select(Evaluation.submission_id).where(
        Evaluation.assignment_id == assignment.id, Evaluation.track == PRIVATE_TRACKS, Evaluation.result_key == key,
        Evaluation.status.in_((DONE, RUNNING, QUEUED)))))
    rows = crud.student_assignments(session, assignment_id=assignment.id).values()
    finals = [row.final_submission_id for row in rows if row.final_at is not None and row.final_submission_id]
    wanted = [*crud.ready_baseline_submissions(session), *crud.submissions_by_id(session, ids=finals).values()]
    jobs = []
    for submission in wanted:
        if submission.id not in covered:
            _, job = crud.create_evaluation(session, submission=submission, assignment=assignment,
                                            settings=assignment.private_settings(), result_key=key,
                                            max_attempts=max_attempts, priority=LOW, track=PRIVATE_TRACKS)
            jobs.append(job)
    return jobs
