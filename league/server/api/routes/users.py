"""Accounts: who am I; instructors create students (one, or a CSV roster) and revoke them."""
from __future__ import annotations

import csv
import io

from fastapi import APIRouter, HTTPException, Request, status
from fastapi.concurrency import run_in_threadpool
from starlette.datastructures import UploadFile  # what a parsed form holds

from league.server.api.deps import CurrentUser, Id, InstructorUser, SessionDep, SettingsDep
from league.server.db import crud
from league.server.db.models import STUDENT, User
from league.server.schemas import QuotaOut, RosterCreated, UserCreate, UserCreated, UserMe, UserOut

router = APIRouter(prefix="/users", tags=["users"])
MAX_ROSTER_BYTES = 1024 * 1024


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
                                       created_by=instructor)
    except crud.InvalidName as error:
        raise HTTPException(status.HTTP_409_CONFLICT, str(error)) from error
    session.commit()
    return created_out(user, token)


ROSTER_FORM = {"requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
    "type": "object", "required": ["file"], "properties": {
        "file": {"type": "string", "format": "binary", "description": "CSV with a `name` column (or one name a line)"}
    }}}}}}


@router.post("/roster", response_model=RosterCreated, status_code=status.HTTP_201_CREATED, openapi_extra=ROSTER_FORM)
async def create_roster(request: Request, instructor: InstructorUser) -> RosterCreated:
    """Create the students of a CSV roster; names already taken are skipped and listed (late
    enrolments: upload the whole roster again). The response holds the new tokens (shown once).
    The body is read only once the instructor's token is accepted."""
    async with request.form(max_files=1, max_fields=0) as form:
        file = form.get("file")
        if not isinstance(file, UploadFile):
            raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "send the roster as the multipart field `file`")
        data = await file.read(MAX_ROSTER_BYTES + 1)
    return await run_in_threadpool(create_students, request.app.state.sessions, instructor.id, roster_names(data))


def create_students(sessions, instructor_id: int, names: list[str]) -> RosterCreated:
    """Every new student of the list, or none if a name is invalid (the 409 names what was wrong)."""
    with sessions() as session:
        instructor = session.get(User, instructor_id)
        created, skipped, problems = [], [], []
        for name in names:
            try:
                created.append(crud.create_user(session, name=name, role=STUDENT, course=instructor.course,
                                                created_by=instructor))
            except crud.NameTaken:
                skipped.append(name.strip())
            except crud.InvalidName as error:
                problems.append(str(error))
        if problems:
            session.rollback()
            raise HTTPException(status.HTTP_409_CONFLICT, "no student was created: " + "; ".join(problems[:20]))
        session.commit()
        return RosterCreated(created=[created_out(user, token) for user, token in created], skipped=skipped)


def roster_names(data: bytes) -> list[str]:
    if len(data) > MAX_ROSTER_BYTES:
        raise HTTPException(status.HTTP_413_CONTENT_TOO_LARGE, "roster too large (1 MB at most)")
    try:
        rows = [row for row in csv.reader(io.StringIO(data.decode("utf-8-sig"))) if any(c.strip() for c in row)]
    except (UnicodeDecodeError, csv.Error) as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"not a UTF-8 CSV file: {error}") from error
    header = [cell.strip().lower() for cell in rows[0]] if rows else []
    column = header.index("name") if "name" in header else 0
    names = [row[column].strip() for row in rows[1 if "name" in header else 0:] if len(row) > column]
    if not names:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "the roster holds no names")
    if len(set(names)) != len(names):
        raise HTTPException(status.HTTP_409_CONFLICT, "the roster names a student twice")
    return names


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
    session.commit()
    return user_out(user)


@router.post("/{user_id}/token", response_model=UserCreated)
def reissue_token(user_id: Id, session: SessionDep, instructor: InstructorUser) -> UserCreated:
    """Give a student a new token (the old one stops working; a revoked account is restored)."""
    user = course_student(session, instructor, user_id)
    token = crud.reissue_token(session, user=user)
    session.commit()
    return created_out(user, token)
