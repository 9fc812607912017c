"""Liveness for load balancers and tests."""
from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import text

from league.server.api.deps import QueueDep, SessionDep, SettingsDep
from league.server.sandbox.process import sandbox_isolation
from league.server.schemas import Health

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health)
def read_health(session: SessionDep, queue: QueueDep, settings: SettingsDep) -> Health:
    """The database answers, the queue is reachable, and how sandboxes are isolated here."""
    session.execute(text("SELECT 1"))
    isolation = sandbox_isolation(settings.sandbox_uid_base)  # found at start-up
    return Health(status="ok", database=session.get_bind().dialect.name, queue=type(queue.huey).__name__,
                  queued_jobs=queue.pending(),
                  sandbox={**isolation.to_dict(), "required": settings.sandbox_require_isolation})
