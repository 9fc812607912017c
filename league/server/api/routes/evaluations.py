"""The course's evaluation settings (a change re-evaluates what it concerns), and re-running evaluations."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException, status
from sqlalchemy import select

from league.server.course import audit
from league.server.api.deps import (
    CurrentUser, InstructorUser, QueueDep, SessionDep, SettingsDep, check_env_options, user_course,
)
from league.server.api.schemas import EvaluationSettings, EvaluationSettingsChange, RerunOut, RerunRequest, UploadLimits
from league.server.course.results import change_settings, queue_evaluation
from league.server.db import crud
from league.server.db.models import LOW, NORMAL, PUBLIC_TRACKS, READY, Assignment, Evaluation, Submission, User

router = APIRouter(tags=["evaluations"])


@router.get("/settings/evaluation", response_model=EvaluationSettings)
def read_evaluation_settings(user: CurrentUser, session: SessionDep) -> EvaluationSettings:
    """The public seed, episode count and environment options of the course's default assignment (its
    oldest; every assignment's: /api/assignments)."""
    return EvaluationSettings(**default_assignment(session, user).evaluation_settings())


@router.get("/settings/limits", response_model=UploadLimits)
def read_upload_limits(settings: SettingsDep) -> UploadLimits:
    """The size, quota and sandbox limits an upload is validated against (public)."""
    return UploadLimits(**{name: getattr(settings, name) for name in UploadLimits.model_fields})


@router.put("/settings/evaluation", response_model=EvaluationSettingsChange)
def update_evaluation_settings(body: EvaluationSettings, instructor: InstructorUser, session: SessionDep,
                               queue: QueueDep, settings: SettingsDep) -> EvaluationSettingsChange:
    """Change the default assignment's settings: results of other settings no longer rank (stale) and
    every ready submission without a result of these settings is evaluated again, after the students'
    own jobs (PATCH /api/assignments/{id} does the same for any assignment)."""
    check_env_options(body.env_options)
    assignment = default_assignment(session, instructor)
    before = assignment.evaluation_settings()
    change = change_settings(session, assignment=assignment, settings=body.model_dump(),
                             max_attempts=settings.max_job_attempts)
    audit.record(session, actor=instructor, action=audit.SETTINGS, target_kind="course",
                 target_id=assignment.course_id, course_id=assignment.course_id, assignment_id=assignment.id,
                 settings=body.model_dump(), reevaluating=change.reevaluated,
                 **audit.changes(before, assignment.evaluation_settings()))
    session.commit()
    for job in change.queued:
        queue.enqueue(job.id)
    return EvaluationSettingsChange(**assignment.evaluation_settings(), reevaluating=change.reevaluated)


def default_assignment(session: SessionDep, user: User) -> Assignment:
    assignment = crud.default_assignment(session, course_id=user_course(session, user).id)
    if assignment is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "the course has no assignment")
    return assignment


@router.post("/evaluations/rerun", response_model=RerunOut, status_code=status.HTTP_202_ACCEPTED)
def rerun_evaluations(body: RerunRequest, instructor: InstructorUser, session: SessionDep, queue: QueueDep,
                      settings: SettingsDep) -> RerunOut:
    """Evaluate again, with its assignment's current settings, one ready submission or all of the
    course's (those at low priority: after the students' own jobs); the baselines with the default
    assignment's."""
    if body.all == (body.submission_id is not None):
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "give either submission_id or all=true")
    submissions = (crud.course_submissions(session, course_id=instructor.course_id, status=READY) if body.all
                   else [ready_submission(session, instructor, body.submission_id)])
    priority = LOW if body.all else NORMAL  # a whole course's backlog waits for the students' own jobs
    fallback = default_assignment(session, instructor)
    before = None if body.all else latest_result(session, body.submission_id)
    jobs = [queue_evaluation(session, submission=s, max_attempts=settings.max_job_attempts, priority=priority,
                             assignment=None if s.owner.course_id else fallback) for s in submissions]
    changed = {} if body.all else {"before": before, "after": {"evaluation_id": jobs[0].evaluation_id,
                                                                 "status": "queued"}}
    audit.record(session, actor=instructor, action=audit.RERUN, target_kind="submission",
                 target_id=None if body.all else body.submission_id, all=body.all, queued=len(jobs), **changed)
    session.commit()
    for job in jobs:
        queue.enqueue(job.id)
    return RerunOut(queued=[s.id for s in submissions])


def latest_result(session: SessionDep, submission_id: int) -> dict | None:
    """The submission's latest public result, as the audit log keeps what a re-run replaces."""
    latest = session.scalar(select(Evaluation).where(Evaluation.submission_id == submission_id,
                                                     Evaluation.track == PUBLIC_TRACKS).order_by(Evaluation.id.desc()))
    return None if latest is None else audit.snapshot(latest, ["id", "status", "completed", "mean_return"])


def ready_submission(session: SessionDep, instructor: User, submission_id: int) -> Submission:
    submission = session.get(Submission, submission_id)
    if submission is None or submission.owner.course_id not in (instructor.course_id, None):
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such submission in your course")
    if submission.status != READY:
        raise HTTPException(status.HTTP_409_CONFLICT,
                            f"submission {submission_id} is {submission.status}: only ready submissions are evaluated")
    return submission
