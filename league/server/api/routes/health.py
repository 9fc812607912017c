"""Liveness for load balancers and tests."""
from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import text

from league.server.api.deps import QueueDep, SessionDep
from league.server.schemas import Health

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health)
def read_health(session: SessionDep, queue: QueueDep) -> Health:
    """The database answers and the queue is reachable."""
    session.execute(text("SELECT 1"))
    return Health(status="ok", database=session.get_bind().dialect.name, queue=type(queue.huey).__name__,
                  queued_jobs=queue.pending())
