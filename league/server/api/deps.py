"""Shared dependencies of the routes, as Annotated aliases."""
from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from league.server.config import Settings
from league.server.db import crud
from league.server.db.models import INSTRUCTOR, User
from league.server.storage import BlobStore
from league.server.taskqueue import JobQueue

bearer = HTTPBearer(auto_error=False, description="the API token printed by `league users add` or the roster")


# The cheap dependencies are `async def`: FastAPI runs them in the event loop instead of handing
# each one to the thread pool (a hop that costs more than the work under load).


async def get_settings(request: Request) -> Settings:
    return request.app.state.settings


async def get_session(request: Request) -> AsyncIterator[Session]:
    """A session per request; opening one does no I/O (the first query, in the handler's thread, does)."""
    with request.app.state.sessions() as session:
        yield session


async def get_queue(request: Request) -> JobQueue:
    return request.app.state.queue


async def get_store(request: Request) -> BlobStore:
    return request.app.state.store


SettingsDep = Annotated[Settings, Depends(get_settings)]
SessionDep = Annotated[Session, Depends(get_session)]
QueueDep = Annotated[JobQueue, Depends(get_queue)]
StoreDep = Annotated[BlobStore, Depends(get_store)]


def unauthorized(detail: str) -> HTTPException:
    return HTTPException(status.HTTP_401_UNAUTHORIZED, detail, headers={"WWW-Authenticate": "Bearer"})


def get_current_user(session: SessionDep,
                     credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> User:
    if credentials is None:
        raise unauthorized("missing token: send the header Authorization: Bearer TOKEN")
    user = crud.user_by_token(session, token=credentials.credentials)
    if user is None:
        raise unauthorized("invalid token")
    if not user.active:
        raise unauthorized("this account was revoked")
    return user


CurrentUser = Annotated[User, Depends(get_current_user)]


async def get_instructor(user: CurrentUser) -> User:
    if user.role != INSTRUCTOR:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only instructors may do this")
    return user


InstructorUser = Annotated[User, Depends(get_instructor)]
