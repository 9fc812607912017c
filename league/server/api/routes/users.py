"""Accounts: who am I; instructors create students (one, or a roster: league/server/course/roster.py) and
revoke them."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request, status
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.exc import IntegrityError
from starlette.datastructures import UploadFile  # what a parsed form holds

from league.server.api.deps import CurrentUser, Id, InstructorUser, SessionDep, SessionsDep, SettingsDep, StoreDep
from league.server.course import audit
from league.server.course.erasure import DeletionRefused, delete_student, write_out
from league.server.course.roster import DELIMITERS, MAX_ROSTER_BYTES, RosterError, import_roster, read_roster
from league.server.db import crud
from league.server.db.models import STUDENT, User
from league.server.api.schemas import (
    QuotaOut, RosterCreated, RosterFormat, RosterLine, UserCreate, UserCreated, UserMe, UserOut,
)

router = APIRouter(prefix="/users", tags=["users"])


def user_out(user: User) -> UserOut:
    return UserOut.model_validate(user)


def created_out(user: User, token: str) -> UserCreated:
    return UserCreated(**user_out(user).model_dump(), token=token)


@router.get("/me", response_model=UserMe)
def read_me(user: CurrentUser, session: SessionDep, settings: SettingsDep) -> UserMe:
    """The account of the token, and (students) how many uploads their quota has left."""
    quota = None
    if user.role == STUDENT:
        usage = crud.quota_usage(session, owner=user, limit=settings.quota_per_day)
        quota = QuotaOut(limit=usage.limit, used=usage.used, remaining=max(usage.limit - usage.used, 0),
                         next_free_at=usage.next_free_at)
    return UserMe(**user_out(user).model_dump(), upload_quota=quota)


@router.get("", response_model=list[UserOut])
def read_users(session: SessionDep, instructor: InstructorUser) -> list[UserOut]:
    """Users of the instructor's course."""
    return [user_out(user) for user in crud.course_users(session, course_id=instructor.course_id)]


@router.post("", response_model=UserCreated, status_code=status.HTTP_201_CREATED)
def create_student(body: UserCreate, session: SessionDep, instructor: InstructorUser) -> UserCreated:
    """Create a student in the instructor's course; the response holds their token (shown once)."""
    try:
        user, token = crud.create_user(session, name=body.name, role=STUDENT, course=instructor.course,
                                       created_by=instructor, email=body.email, student_id=body.student_id)
    except crud.AccountTaken as error:
        raise HTTPException(status.HTTP_409_CONFLICT, str(error)) from error
    except crud.InvalidAccount as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(error)) from error
    audit.record(session, actor=instructor, action=audit.CREATE_USER, target_kind="user", target_id=user.id)
    session.commit()
    return created_out(user, token)


ROSTER_FORM = {"requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
    "type": "object", "required": ["file"], "properties": {
        "file": {"type": "string", "format": "binary",
                 "description": "CSV (comma, semicolon or tab) with a header naming `name` (or first and last "
                                "name), `email`, `student id`; or one name a line"}
    }}}}}}


@router.post("/roster", response_model=RosterCreated, status_code=status.HTTP_201_CREATED, openapi_extra=ROSTER_FORM)
async def create_roster(request: Request, instructor: InstructorUser, sessions: SessionsDep) -> RosterCreated:
    """Create the students of a roster as spreadsheets export it. Lines are independent: the good ones
    are created, every bad one is listed in `errors` with its line number, and students enrolled
    already are skipped (upload the whole roster again for late enrolments, or once its errors are
    fixed). The response holds the new tokens (shown once). The body is read only once the
    instructor's token is accepted."""
    async with request.form(max_files=1, max_fields=0) as form:
        file = form.get("file")
        if not isinstance(file, UploadFile):
            raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "send the roster as the multipart field `file`")
        data = await file.read(MAX_ROSTER_BYTES + 1)
    if len(data) > MAX_ROSTER_BYTES:
        raise HTTPException(status.HTTP_413_CONTENT_TOO_LARGE, "roster too large (1 MB at most)")
    return await run_in_threadpool(create_students, sessions, instructor.id, data)


def create_students(sessions, instructor_id: int, data: bytes) -> RosterCreated:
    """The roster read and imported in one transaction (422: a file that cannot be read at all)."""
    try:
        roster = read_roster(data)
    except RosterError as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(error)) from error
    with sessions() as session:
        crud.lock_user(session, user_id=instructor_id)  # one roster at a time (SQLite: the write lock first)
        instructor = session.get(User, instructor_id)
        try:
            report = import_roster(session, course=instructor.course, created_by=instructor, roster=roster)
            audit.record(session, actor=instructor, action=audit.IMPORT_ROSTER, target_kind="roster",
                         created=[user.id for user, _ in report.created], skipped=len(report.skipped),
                         errors=len(report.errors))
            session.commit()
        except IntegrityError as error:  # another instructor's roster named the same students meanwhile
            raise HTTPException(status.HTTP_409_CONFLICT, "another roster was imported at the same time: upload this "
                                "one again (its students created since are skipped)") from error
    return RosterCreated(
        format=RosterFormat(delimiter=DELIMITERS[roster.delimiter], columns=roster.columns, layout=roster.layout),
        created=[created_out(user, token) for user, token in report.created],
        skipped=[RosterLine(**vars(problem)) for problem in report.skipped],
        errors=[RosterLine(**vars(problem)) for problem in report.errors])


def course_student(session: SessionDep, instructor: User, user_id: int) -> User:
    """A student of the instructor's course (another instructor's account is theirs to manage)."""
    user = session.get(User, user_id)
    if user is None or user.course_id != instructor.course_id or user.role != STUDENT:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such student in your course")
    return user


@router.post("/{user_id}/revoke", response_model=UserOut)
def revoke_user(user_id: Id, session: SessionDep, instructor: InstructorUser) -> UserOut:
    """Revoke a student's account: its token stops working; its submissions and results stay."""
    user = course_student(session, instructor, user_id)
    crud.revoke_user(session, user=user)
    audit.record(session, actor=instructor, action=audit.REVOKE, target_kind="user", target_id=user.id)
    session.commit()
    return user_out(user)


@router.post("/{user_id}/token", response_model=UserCreated)
def reissue_token(user_id: Id, session: SessionDep, instructor: InstructorUser) -> UserCreated:
    """Give a student a new token (the old one stops working; a revoked account is restored)."""
    user = course_student(session, instructor, user_id)
    token = crud.reissue_token(session, user=user)
    audit.record(session, actor=instructor, action=audit.TOKEN, target_kind="user", target_id=user.id)
    session.commit()
    return created_out(user, token)


@router.delete("/{user_id}", status_code=status.HTTP_204_NO_CONTENT)
def erase_student(user_id: Id, session: SessionDep, instructor: InstructorUser, store: StoreDep) -> None:
    """Delete a student and their data for good (league.server.course.erasure): account, token, submissions,
    model files, evaluations; races other students took part in keep their results, the student's cars
    shown as "deleted student". 409 while a championship heat with their car is still to race."""
    user = course_student(session, instructor, user_id)
    if not crud.lock_user(session, user_id=user.id):  # no upload or race of theirs starts meanwhile
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such student in your course")  # deleted meanwhile
    try:
        erased = delete_student(session, user=user)
    except DeletionRefused as refusal:
        raise HTTPException(status.HTTP_409_CONFLICT, str(refusal)) from refusal
    audit.record(session, actor=instructor, action=audit.DELETE_USER, target_kind="user", target_id=user_id,
                 note="student and their data deleted", **erased.summary())
    session.commit()
    write_out(session.get_bind())
    for sha256 in erased.blobs:
        store.remove(sha256)
