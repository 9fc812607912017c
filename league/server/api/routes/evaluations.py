"""The course's evaluation settings, and re-running evaluations after a change."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException, status

import league
from league.server.api.deps import CurrentUser, InstructorUser, QueueDep, SessionDep, SettingsDep
from league.server.db import crud
from league.server.db.models import READY, Course, Submission, User
from league.server.schemas import EvaluationSettings, RerunOut, RerunRequest
from league.server.tasks import queue_evaluation

router = APIRouter(tags=["evaluations"])


def user_course(session: SessionDep, user: User) -> Course:
    course = user.course or crud.first_course(session)
    if course is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no course yet")
    return course


@router.get("/settings/evaluation", response_model=EvaluationSettings)
def read_evaluation_settings(user: CurrentUser, session: SessionDep) -> EvaluationSettings:
    """The seed, episode count and environment options every submission is evaluated with."""
    return EvaluationSettings(**user_course(session, user).evaluation_settings())


@router.put("/settings/evaluation", response_model=EvaluationSettings)
def update_evaluation_settings(body: EvaluationSettings, instructor: InstructorUser,
                               session: SessionDep) -> EvaluationSettings:
    """Change the evaluation settings (existing results stay until you re-run them)."""
    check_env_options(body.env_options)
    course = crud.set_evaluation_settings(session, course=user_course(session, instructor), seed=body.seed,
                                          episodes=body.episodes, env_options=body.env_options)
    session.commit()
    return EvaluationSettings(**course.evaluation_settings())


def check_env_options(options: dict) -> None:
    if "observation" in options:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT,
                            "observation is not an evaluation setting: it follows each agent's input size")
    try:
        league.RaceOptions.from_kwargs(**options)
    except (TypeError, ValueError) as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"invalid env_options: {error}") from error


@router.post("/evaluations/rerun", response_model=RerunOut, status_code=status.HTTP_202_ACCEPTED)
def rerun_evaluations(body: RerunRequest, instructor: InstructorUser, session: SessionDep, queue: QueueDep,
                      settings: SettingsDep) -> RerunOut:
    """Evaluate again, with the current settings, one ready submission or all of the course's."""
    if body.all == (body.submission_id is not None):
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "give either submission_id or all=true")
    submissions = (crud.course_submissions(session, course_id=instructor.course_id, status=READY) if body.all
                   else [ready_submission(session, instructor, body.submission_id)])
    course = user_course(session, instructor)
    jobs = [queue_evaluation(session, submission=s, max_attempts=settings.max_job_attempts, course=course)
            for s in submissions]
    session.commit()
    for job in jobs:
        queue.enqueue(job.id)
    return RerunOut(queued=[s.id for s in submissions])


def ready_submission(session: SessionDep, instructor: User, submission_id: int) -> Submission:
    submission = session.get(Submission, submission_id)
    if submission is None or submission.owner.course_id not in (instructor.course_id, None):
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such submission in your course")
    if submission.status != READY:
        raise HTTPException(status.HTTP_409_CONFLICT,
                            f"submission {submission_id} is {submission.status}: only ready submissions are evaluated")
    return submission
