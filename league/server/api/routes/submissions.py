"""Submissions: upload a model, follow its validation and evaluation."""
from __future__ import annotations

from pathlib import PurePath
from typing import Annotated

from fastapi import APIRouter, File, Form, HTTPException, UploadFile, status
from sqlalchemy.exc import IntegrityError

from league.server.api.deps import CurrentUser, QueueDep, SessionDep, SettingsDep, StoreDep
from league.server.db import crud
from league.server.db.models import INSTRUCTOR, READY, STUDENT, Submission, User
from league.server.racing import active_submission_ids
from league.server.schemas import (
    EvaluationDetail, EvaluationOut, SubmissionCreated, SubmissionDetail, SubmissionOut, SubmissionUpdate,
)
from league.server.storage import EmptyFile, FileTooLarge, model_kind_of

router = APIRouter(prefix="/submissions", tags=["submissions"])


def model_kind(filename: str | None) -> str:
    kind = model_kind_of(filename)
    if kind is None:
        suffix = PurePath(filename or "").suffix or "(none)"
        raise HTTPException(status.HTTP_415_UNSUPPORTED_MEDIA_TYPE,
                            f"unsupported file type {suffix!r}: upload an .onnx or a TorchScript .pt file")
    return kind


@router.post("", response_model=SubmissionCreated, status_code=status.HTTP_201_CREATED)
def create_submission(file: Annotated[UploadFile, File(description="an ONNX (.onnx) or TorchScript (.pt) model")],
                      user: CurrentUser, session: SessionDep, settings: SettingsDep, store: StoreDep,
                      queue: QueueDep,
                      name: Annotated[str | None, Form(max_length=100, description="default: the file name")] = None,
                      ) -> SubmissionCreated:
    """Upload a model; it is validated in a sandbox, then evaluated on the course's tracks."""
    kind = model_kind(file.filename)
    if user.role == STUDENT:
        check_quota(session, user, settings.quota_per_day)
    try:
        sha256, size = store.save(file.file, max_bytes=settings.max_upload_bytes)
    except FileTooLarge as error:
        raise HTTPException(status.HTTP_413_CONTENT_TOO_LARGE, str(error)) from error
    except EmptyFile as error:
        raise HTTPException(status.HTTP_400_BAD_REQUEST, "the file is empty") from error
    keep_blob(session, sha256, store)
    display_name = (name or "").strip() or PurePath(file.filename).stem
    submission, job = crud.create_submission(session, owner=user, name=display_name[:100],
                                             filename=PurePath(file.filename).name[:255], kind=kind, sha256=sha256,
                                             size=size, max_attempts=settings.max_job_attempts)
    session.commit()
    queue.enqueue(job.id)
    return SubmissionCreated(id=submission.id, status=submission.status)


def keep_blob(session: SessionDep, sha256: str, store: StoreDep) -> None:
    """The bytes go to the database too, for workers on other machines."""
    try:
        crud.save_blob(session, sha256=sha256, data=store.path(sha256).read_bytes())
        session.commit()
    except IntegrityError:  # the same file, uploaded at the same moment by someone else
        session.rollback()


def check_quota(session: SessionDep, user: User, limit: int) -> None:
    usage = crud.quota_usage(session, owner=user, limit=limit)
    if usage.exhausted:
        raise HTTPException(status.HTTP_429_TOO_MANY_REQUESTS,
                            f"quota reached: {limit} submissions per 24 hours (rejected ones do not count); "
                            f"next free slot at {usage.next_free_at.isoformat(timespec='seconds')}")


@router.get("", response_model=list[SubmissionOut])
def read_submissions(user: CurrentUser, session: SessionDep, all: bool = False) -> list[SubmissionOut]:
    """Your submissions, newest first (instructors: `all=true` for the whole course and the baselines)."""
    if all and user.role == INSTRUCTOR:
        submissions = crud.course_submissions(session, course_id=user.course_id)[::-1]
    else:
        submissions = crud.submissions_of(session, owner_ids=[user.id])
    evaluations = crud.latest_evaluations(session, submission_ids=[s.id for s in submissions])
    active = active_submission_ids(session, owners=list({s.owner_id: s.owner for s in submissions}.values()))
    return [submission_out(s, evaluations.get(s.id), s.id in active) for s in submissions]


@router.get("/{submission_id}", response_model=SubmissionDetail)
def read_submission(submission_id: int, user: CurrentUser, session: SessionDep) -> SubmissionDetail:
    """One submission in full: status, error, sandbox log and its latest evaluation with every episode."""
    submission = session.get(Submission, submission_id)
    if submission is None or not may_read(user, submission):
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such submission")
    evaluation = crud.latest_evaluation(session, submission_id=submission.id)
    detail = EvaluationDetail.model_validate(evaluation) if evaluation else None
    return SubmissionDetail(**submission_fields(submission), log=submission.log, evaluation=detail,
                            active=submission.status == READY  # only a ready one can be: no query while polling
                            and submission.id in active_submission_ids(session, owners=[submission.owner]))


@router.patch("/{submission_id}", response_model=SubmissionOut)
def update_submission(submission_id: int, body: SubmissionUpdate, user: CurrentUser,
                      session: SessionDep) -> SubmissionOut:
    """Pick the submission that races in championships, or let other students race against it."""
    submission = session.get(Submission, submission_id)
    if submission is None or submission.owner_id != user.id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such submission of yours")
    if body.active is True:
        if submission.status != READY:
            raise HTTPException(status.HTTP_409_CONFLICT, f"submission {submission_id} is {submission.status}: "
                                                          "only a ready submission can race in championships")
        user.active_submission_id = submission.id
    elif body.active is False and user.active_submission_id == submission.id:
        user.active_submission_id = None  # back to the default: the latest ready one
    if body.public is not None:
        submission.public = body.public
    session.commit()
    evaluation = crud.latest_evaluation(session, submission_id=submission.id)
    return submission_out(submission, evaluation, submission.id in active_submission_ids(session, owners=[user]))


def may_read(user: User, submission: Submission) -> bool:
    """Owners and their course's instructors; others see public results only (the leaderboard)."""
    if submission.owner_id == user.id:
        return True
    owner_course = submission.owner.course_id
    return user.role == INSTRUCTOR and (owner_course == user.course_id or owner_course is None)


COLUMNS = [name for name in SubmissionOut.model_fields if name not in ("owner", "evaluation", "active")]


def submission_fields(submission: Submission) -> dict:
    return {**{name: getattr(submission, name) for name in COLUMNS}, "owner": submission.owner.name}


def submission_out(submission: Submission, evaluation, active: bool) -> SubmissionOut:
    return SubmissionOut(**submission_fields(submission), active=active,
                         evaluation=EvaluationOut.model_validate(evaluation) if evaluation else None)
