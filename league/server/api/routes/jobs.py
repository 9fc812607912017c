"""Jobs, for instructors watching the workers."""
from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import select

from league.server.api.deps import InstructorUser, SessionDep
from league.server.db.models import Job
from league.server.schemas import JobOut

router = APIRouter(prefix="/jobs", tags=["jobs"])


@router.get("", response_model=list[JobOut])
def read_jobs(_: InstructorUser, session: SessionDep, status: str | None = None, limit: int = 100) -> list[Job]:
    """The latest jobs, newest first, optionally of one status (queued, running, done, failed)."""
    query = select(Job).order_by(Job.id.desc()).limit(min(max(limit, 1), 1000))
    if status:
        query = query.where(Job.status == status)
    return list(session.scalars(query))
