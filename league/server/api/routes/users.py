"""Accounts: who am I; instructors create students (one, or a CSV roster) and revoke them."""
from __future__ import annotations

import csv
import io
from typing import Annotated

from fastapi import APIRouter, File, HTTPException, UploadFile, status

from league.server.api.deps import CurrentUser, InstructorUser, SessionDep
from league.server.db import crud
from league.server.db.models import STUDENT, User
from league.server.schemas import UserCreate, UserCreated, UserOut

router = APIRouter(prefix="/users", tags=["users"])
MAX_ROSTER_BYTES = 1024 * 1024


def user_out(user: User) -> UserOut:
    return UserOut.model_validate(user)


def created_out(user: User, token: str) -> UserCreated:
    return UserCreated(**user_out(user).model_dump(), token=token)


@router.get("/me", response_model=UserOut)
def read_me(user: CurrentUser) -> UserOut:
    """The account of the token."""
    return user_out(user)


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


@router.post("/roster", response_model=list[UserCreated], status_code=status.HTTP_201_CREATED)
def create_roster(file: Annotated[UploadFile, File(description="CSV with a `name` column (or one name a line)")],
                  session: SessionDep, instructor: InstructorUser) -> list[UserCreated]:
    """Create the students of a CSV roster, all or none; the response holds their tokens (shown once)."""
    names = roster_names(file.file.read(MAX_ROSTER_BYTES + 1))
    created, problems = [], []
    for name in names:
        try:
            created.append(crud.create_user(session, name=name, role=STUDENT, course=instructor.course,
                                            created_by=instructor))
        except crud.InvalidName as error:
            problems.append(str(error))
    if problems:
        session.rollback()
        raise HTTPException(status.HTTP_409_CONFLICT, "no student was created: " + "; ".join(problems[:20]))
    session.commit()
    return [created_out(user, token) for user, token in created]


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


def course_user(session: SessionDep, instructor: User, user_id: int) -> User:
    user = session.get(User, user_id)
    if user is None or user.course_id != instructor.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such user in your course")
    return user


@router.post("/{user_id}/revoke", response_model=UserOut)
def revoke_user(user_id: int, session: SessionDep, instructor: InstructorUser) -> UserOut:
    """Revoke an account: its token stops working; its submissions and results stay."""
    user = course_user(session, instructor, user_id)
    if user.id == instructor.id:
        raise HTTPException(status.HTTP_409_CONFLICT, "you cannot revoke your own account")
    crud.revoke_user(session, user=user)
    session.commit()
    return user_out(user)


@router.post("/{user_id}/token", response_model=UserCreated)
def reissue_token(user_id: int, session: SessionDep, instructor: InstructorUser) -> UserCreated:
    """Give a student a new token (the old one stops working; a revoked account is restored)."""
    user = course_user(session, instructor, user_id)
    token = crud.reissue_token(session, user=user)
    session.commit()
    return created_out(user, token)
