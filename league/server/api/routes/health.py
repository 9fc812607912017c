"""Liveness for load balancers, monitoring and tests."""
from __future__ import annotations

from fastapi import APIRouter, Response, status

from league.server.api.deps import SessionDep, SettingsDep
from league.server.jobs.leases import queue_depth
from league.server.jobs.registry import live_workers
from league.server.sandbox.process import sandbox_isolation
from league.server.schemas import Health, WorkerOut

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health, responses={503: {"model": Health, "description": "jobs wait and no "
                                                                                                "worker is alive"}})
def read_health(session: SessionDep, settings: SettingsDep, response: Response) -> Health:
    """The database answers; the queued jobs and the live workers; how sandboxes are isolated here.
    503 when jobs have waited longer than worker_silent_after_s and no worker was heard from meanwhile."""
    queued, oldest_s = queue_depth(session)
    workers = live_workers(session, settings.worker_silent_after_s)
    silent_s = settings.worker_silent_after_s
    reason = None
    if queued and not workers and oldest_s > silent_s:
        reason = (f"{queued} job{'s' if queued > 1 else ''} queued, the oldest for {oldest_s:.0f} s, and no worker "
                  f"heard from in the last {silent_s:g} s: start `league worker` (or `league serve` without "
                  f"--no-worker) on this database")
        response.status_code = status.HTTP_503_SERVICE_UNAVAILABLE
    isolation = sandbox_isolation(settings.sandbox_uid_base)  # found at start-up
    return Health(status="no_worker" if reason else "ok", reason=reason, database=session.get_bind().dialect.name,
                  queued_jobs=queued, oldest_queued_s=oldest_s,
                  workers=[WorkerOut.model_validate(worker) for worker in workers],
                  sandbox={**isolation.to_dict(), "required": settings.sandbox_require_isolation})
