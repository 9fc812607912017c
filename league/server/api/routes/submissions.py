"""Submissions: upload a model, follow its validation and evaluation."""
from __future__ import annotations

import contextlib
import re
from pathlib import PurePath

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response, status
from fastapi.security import HTTPAuthorizationCredentials
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.exc import DBAPIError
from starlette.datastructures import UploadFile  # what a parsed form holds
from starlette.types import ASGIApp, Receive, Scope, Send

from league.server.api.cache import PRIVATE, etag_response
from league.server.api.deps import (
    MAX_ID, CurrentUser, Id, ServicesDep, SessionDep, bearer, check_jobs_in_flight, check_upload_quota,
    get_current_user, lock_account, user_course,
)
from league.server.core.logs import log_refused_upload
from league.server.course.assignments import UploadRefused, check_upload, private_visible, upload_assignment
from league.server.db import crud
from league.server.db.models import (
    BASELINE, INSTRUCTOR, PUBLIC_TRACKS, READY, STUDENT, Assignment, Evaluation, Submission, User,
)
from league.server.course.races import active_submission_ids
from league.server.course.results import settings_key, submissions_current_keys
from league.server.services import Services
from league.server.api.schemas import (
    DbId, EpisodeOut, EpisodePage, EvaluationOut, EvaluationSummary, SubmissionCreated, SubmissionDetail,
    SubmissionLinks, SubmissionOut, SubmissionUpdate,
)
from league.server.storage import EmptyFile, FileTooLarge
from league.validation.files import model_kind_of, unsupported

router = APIRouter(prefix="/submissions", tags=["submissions"])


def model_kind(filename: str | None) -> str:
    kind = model_kind_of(filename)
    if kind is None:
        raise HTTPException(status.HTTP_415_UNSUPPORTED_MEDIA_TYPE, unsupported(filename or ""))
    return kind


UPLOAD_FORM = {"requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
    "type": "object", "required": ["file"], "properties": {
        "file": {"type": "string", "format": "binary", "description": "an ONNX (.onnx) or TorchScript (.pt) model"},
        "name": {"type": "string", "maxLength": 100, "description": "default: the file name"},
        "assignment": {"type": "string", "maxLength": 100,
                       "description": "an assignment's id or name; default: the only one open to you"}}}}}}}


@router.post("", response_model=SubmissionCreated, status_code=status.HTTP_201_CREATED, openapi_extra=UPLOAD_FORM)
async def create_submission(request: Request, user: CurrentUser, services: ServicesDep) -> SubmissionCreated:
    """Upload a model (multipart `file`, optional `name` and `assignment`) to an assignment: it is
    validated in a sandbox, then evaluated on the assignment's public tracks. The body is read only
    once the token is accepted."""
    async with request.form(max_files=1, max_fields=2) as form:
        file, name, wanted = form.get("file"), form.get("name"), form.get("assignment")
        try:
            if not isinstance(file, UploadFile) or not file.filename:
                raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT,
                                    "send the model as the multipart field `file` (with its file name)")
            if name is not None and (not isinstance(name, str) or len(name) > 100):
                raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "name: at most 100 characters")
            if wanted is not None and (not isinstance(wanted, str) or len(wanted) > 100):
                raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "assignment: an id or a name")
            kind = model_kind(file.filename)
            return await run_in_threadpool(submit, services, user, file, name, kind, wanted)
        except HTTPException as refusal:
            log_refused_upload(user.id, str(refusal.detail), getattr(file, "size", None))
            raise


def submit(services: Services, user: User, file: UploadFile, name: str | None, kind: str,
           wanted: str | None = None) -> SubmissionCreated:
    """Store the file, then, in one transaction holding the student's row, check the assignment's
    window, their quotas and jobs in flight and add the submission: parallel uploads never pass a
    limit. A refused upload's file is not kept."""
    settings, store = services.settings, services.store
    try:
        sha256, size = store.save(file.file, max_bytes=settings.max_upload_bytes)
    except FileTooLarge as error:
        raise HTTPException(status.HTTP_413_CONTENT_TOO_LARGE, str(error)) from error
    except EmptyFile as error:
        raise HTTPException(status.HTTP_400_BAD_REQUEST, "the file is empty") from error
    display_name = (name or "").strip() or PurePath(file.filename).stem
    try:
        with services.sessions.begin() as session:
            lock_account(session, user)
            now = services.clock.now()
            try:
                assignment = upload_assignment(session, user=user, course=user_course(session, user), wanted=wanted,
                                               now=now)
                late = check_upload(session, assignment=assignment, user=user, now=now)
            except UploadRefused as refused:
                raise HTTPException(refused.status, str(refused)) from None
            if user.role == STUDENT:
                check_upload_quota(session, user, settings.quota_per_day)
                check_jobs_in_flight(session, user, settings.max_jobs_in_flight)
            crud.save_blob(session, sha256=sha256, data=store.path(sha256).read_bytes())  # for other machines' workers
            submission, job = crud.create_submission(session, owner=user, assignment=assignment,
                                                     name=display_name[:100],
                                                     filename=PurePath(file.filename).name[:255], kind=kind,
                                                     sha256=sha256, size=size, max_attempts=settings.max_job_attempts,
                                                     late=late, created_at=now)
            created, job_id = SubmissionCreated(id=submission.id, status=submission.status), job.id
    except HTTPException:
        with services.sessions() as session:
            if sha256 not in crud.kept_blobs(session, sha256s=[sha256]):
                store.remove(sha256)
        raise
    services.queue.enqueue(job_id)
    return created


@router.get("", response_model=list[SubmissionOut])
def read_submissions(user: CurrentUser, session: SessionDep, all: bool = False) -> list[SubmissionOut]:
    """Your submissions, newest first (instructors: `all=true` for the whole course and the baselines)."""
    if all and user.role == INSTRUCTOR:
        submissions = crud.course_submissions(session, course_id=user.course_id)[::-1]
    else:
        submissions = crud.submissions_of(session, owner_ids=[user.id])
    owners = list({s.owner_id: s.owner for s in submissions}.values())
    course_id = user_course(session, user).id
    keys = submissions_current_keys(session, submissions, course_id)
    evaluations = crud.latest_evaluations(session, submission_ids=[s.id for s in submissions
                                                                   if s.owner.role != BASELINE], result_keys=keys)
    evaluations.update(crud.latest_evaluations(session, submission_ids=[s.id for s in submissions
                                                                        if s.owner.role == BASELINE],
                                               result_keys=keys, course_id=course_id))
    active = active_submission_ids(session, owners=owners)
    return [submission_out(s, evaluations.get(s.id), keys[s.id], s.id in active) for s in submissions]


NOT_MODIFIED = {304: {"description": "unchanged since the ETag sent in If-None-Match"}}


@router.get("/{submission_id}", response_model=SubmissionDetail, responses=NOT_MODIFIED)
async def read_submission(submission_id: Id, request: Request, services: ServicesDep,
                          credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> Response:
    """One submission's status: validation, sandbox log, its evaluation (the newest of the current
    settings, else the newest) with what produced it, and a link to that evaluation's episodes. Poll
    it with the ETag it sent (If-None-Match): 304 while nothing changed."""
    # StatusAnswers answers the readable ones before routing; here come the refusals (and ids written
    # otherwise, "02"): the same as every route's (the token's dependency, readable_submission)
    answer = await run_in_threadpool(status_answer, services, request, credentials, submission_id)
    if answer is None:
        answer = await run_in_threadpool(refused_status, services, request, credentials, submission_id)
    return answer


STATUS_PATH = re.compile(r"/api/submissions/([1-9][0-9]{0,18})")  # ids as written in links (no "02", "+2")


class StatusAnswers:
    """ASGI middleware (inside the metrics' timer and access log, outside the router): the answer of
    read_submission to `GET /api/submissions/{id}` with a token that may read it, without routing and
    dependency solving, which cost pollers as much CPU as the answer itself. Everything else, a
    refusal, or a database error included, goes on to the app: read_submission answers it as it does
    (the route's own answer is the same, byte for byte: the test sends ids written "02" to it)."""

    def __init__(self, app: ASGIApp, services: Services):
        self.app, self.services = app, services
        # the matched route, as the router leaves it in the scope: the metrics' route label
        self.route = next(route for route in router.routes if getattr(route, "endpoint", None) is read_submission)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] == "GET":
            found = STATUS_PATH.fullmatch(scope["path"])
            if found is not None and int(found[1]) <= MAX_ID:
                request = Request(scope, receive)
                credentials = await bearer(request)
                answer = None
                if credentials is not None:
                    with contextlib.suppress(DBAPIError):  # the route's handler says what it is (database_error)
                        answer = await run_in_threadpool(status_answer, self.services, request, credentials,
                                                         int(found[1]))
                if answer is not None:
                    scope["route"] = self.route
                    await answer(scope, receive, send)
                    return
        await self.app(scope, receive, send)


def status_answer(services: Services, request: Request, credentials: HTTPAuthorizationCredentials | None,
                  submission_id: int) -> Response | None:
    """The status answer, read with two Core statements (crud.status_row, crud.shown_evaluation_row):
    the token's user, the submission, its owner, the assignment whose results count for it and
    whether it races, then the evaluation shown. The rules are those of the ORM's functions that the
    other routes use (get_current_user, may_read, evaluations_course, submissions_current_keys,
    crud.latest_evaluation, active_submission_ids); None for whatever they refuse (refused_status
    refuses it with them)."""
    row = evaluation = key = None
    if credentials is not None:
        with services.engine.connect() as connection:
            row = crud.status_row(connection, token=credentials.credentials, submission_id=submission_id)
            if row_readable(row):
                key = None if row.counted_assignment_id is None else settings_key(
                    {"seed": row.seed, "episodes": row.episodes, "env_options": dict(row.env_options)})
                evaluation = crud.shown_evaluation_row(
                    connection, submission_id=row.id, result_key=key,
                    course_id=row.viewer_course if row.owner_role == BASELINE else None)
    if not row_readable(row):
        return None
    request.state.user_id = row.viewer_id  # for the access log, as get_current_user leaves it
    detail = SubmissionDetail(
        **{name: getattr(row, name) for name in COLUMNS}, owner=row.owner, log=row.log, active=bool(row.active),
        evaluation=None if evaluation is None else EvaluationSummary(**evaluation._mapping,
                                                                     stale=evaluation.result_key != key),
        links=SubmissionLinks(episodes=episodes_link(row.id, evaluation)))
    return etag_response(request, detail.model_dump_json(by_alias=True).encode(), PRIVATE)


def row_readable(row) -> bool:
    """Whether crud.status_row's row is of an active account's token and of a submission it may read
    (may_read) whose evaluations' course it has (evaluations_course)."""
    if row is None or row.viewer_revoked_at is not None or row.id is None:
        return False
    if row.owner_role == BASELINE and row.viewer_course is None:
        return False
    return row.owner_id == row.viewer_id or row.viewer_role == INSTRUCTOR and (
        row.owner_course_id == row.viewer_course_id or row.owner_course_id is None)


def refused_status(services: Services, request: Request, credentials: HTTPAuthorizationCredentials | None,
                   submission_id: int) -> Response:
    """The refusal of a status the Core read did not find readable, by the functions every route refuses
    with (401 for the token, 404 for the submission or the course). If they find it readable after
    all (it changed between the two reads), the status is read once more."""
    with services.sessions() as session:
        user = get_current_user(request, session, credentials)
        submission = readable_submission(session, user, submission_id)
        evaluations_course(session, user, submission)
    answer = status_answer(services, request, credentials, submission_id)
    if answer is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such submission")
    return answer


@router.get("/{submission_id}/episodes", response_model=EpisodePage, responses=NOT_MODIFIED)
def read_episodes(submission_id: Id, request: Request, user: CurrentUser, session: SessionDep,
                  evaluation_id: Annotated[DbId | None, Query(description="default: the latest")] = None,
                  offset: Annotated[int, Query(ge=0, le=10_000)] = 0,
                  limit: Annotated[int, Query(ge=1, le=1000)] = 100) -> Response:
    """The episodes of the submission's evaluation (the one its status shows, or `evaluation_id`: a
    private test's once its assignment is published), in order, paged."""
    submission = readable_submission(session, user, submission_id)
    course_id = evaluations_course(session, user, submission)
    key = submissions_current_keys(session, [submission], course_id)[submission.id]
    evaluation = (crud.latest_evaluation(session, submission_id=submission.id, result_key=key, course_id=course_id)
                  if evaluation_id is None else session.get(Evaluation, evaluation_id))
    if evaluation is None or evaluation.submission_id != submission.id or (
            course_id is not None and evaluation.course_id != course_id) or (
            evaluation.track != PUBLIC_TRACKS
            and not private_visible(session.get(Assignment, evaluation.assignment_id), user)):
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such evaluation of this submission")
    rows, total = crud.episode_page(session, evaluation_id=evaluation.id, offset=offset, limit=limit)
    page = EpisodePage(evaluation_id=evaluation.id, total=total, items=[EpisodeOut.model_validate(r) for r in rows])
    return etag_response(request, page.model_dump_json(by_alias=True).encode(), PRIVATE)


def readable_submission(session: SessionDep, user: User, submission_id: int) -> Submission:
    submission = session.get(Submission, submission_id)
    if submission is None or not may_read(user, submission):
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such submission")
    return submission


def evaluations_course(session: SessionDep, user: User, submission: Submission) -> int | None:
    """The course whose evaluations of the submission `user` is shown: for a baseline (which each course
    evaluates on its own assignments), the user's own, never another course's results or private tests;
    None (any) for a student's, whose evaluations are all of their course."""
    return user_course(session, user).id if submission.owner.role == BASELINE else None


def episodes_link(submission_id: int, evaluation: Evaluation | None) -> str | None:
    return f"/api/submissions/{submission_id}/episodes?evaluation_id={evaluation.id}" if evaluation else None


@router.patch("/{submission_id}", response_model=SubmissionOut)
def update_submission(submission_id: Id, body: SubmissionUpdate, user: CurrentUser,
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
    key = submissions_current_keys(session, [submission])[submission.id]
    evaluation = crud.latest_evaluation(session, submission_id=submission.id, result_key=key)  # their own
    return submission_out(submission, evaluation, key,
                          submission.id in active_submission_ids(session, owners=[user]))


def may_read(user: User, submission: Submission) -> bool:
    """Owners and their course's instructors; others see public results only (the leaderboard)."""
    if submission.owner_id == user.id:
        return True
    owner_course = submission.owner.course_id
    return user.role == INSTRUCTOR and (owner_course == user.course_id or owner_course is None)


COLUMNS = [name for name in SubmissionOut.model_fields if name not in ("owner", "evaluation", "active")]


def submission_fields(submission: Submission) -> dict:
    return {**{name: getattr(submission, name) for name in COLUMNS}, "owner": submission.owner.name}


def submission_out(submission: Submission, evaluation: Evaluation | None, current_key: str | None,
                   active: bool) -> SubmissionOut:
    return SubmissionOut(**submission_fields(submission), active=active,
                         evaluation=evaluation_out(evaluation, current_key, EvaluationOut))


def evaluation_out(evaluation: Evaluation | None, current_key: str | None, model: type[EvaluationOut]):
    """The evaluation as `model`, stale when its key is not the current one."""
    if evaluation is None:
        return None
    return model.model_validate(evaluation).model_copy(update={"stale": evaluation.result_key != current_key})
