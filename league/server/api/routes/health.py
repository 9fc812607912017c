"""Liveness for load balancers, monitoring and tests."""
from __future__ import annotations

from fastapi import APIRouter, Response, status

import league
from league.server.api.deps import SessionDep, SettingsDep, WatchDep
from league.server.api.schemas import Health, WorkerOut
from league.server.db.session import head_revision
from league.server.jobs.leases import queue_depth
from league.server.jobs.registry import is_alive, workers
from league.server.sandbox.process import sandbox_isolation

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health, responses={503: {"model": Health, "description": "no worker is "
                                                                                                "alive, or the "
                                                                                                "schema changed"}})
def read_health(watch: WatchDep, session: SessionDep, settings: SettingsDep, response: Response) -> Health:
    """The database answers; the queued jobs and the workers with their last heartbeat; how sandboxes
    are isolated here. 503 when no worker was heard from in the last worker_silent_after_s seconds,
    whether or not jobs wait ("degraded": an upload would wait for good), or when the database's schema
    is not this process's ("outdated": it was upgraded under it)."""
    queued, oldest_s = queue_depth(session)
    registered = workers(session)
    listed = [WorkerOut(host=worker.host, pid=worker.pid, version=worker.version, started_at=worker.started_at,
                        heartbeat_at=worker.heartbeat_at, alive=is_alive(worker, settings.worker_silent_after_s))
              for worker in registered]
    state, reason = "ok", watch.problem
    if reason:
        state = "outdated"
    elif not any(worker.alive for worker in listed):
        state, reason = "degraded", no_worker(queued, oldest_s, settings.worker_silent_after_s)
    if reason:
        response.status_code = status.HTTP_503_SERVICE_UNAVAILABLE
    isolation = sandbox_isolation(settings.sandbox_uid_base)  # found at start-up
    return Health(status=state, reason=reason, version=league.__version__, schema_revision=head_revision(),
                  database=session.get_bind().dialect.name, queued_jobs=queued, oldest_queued_s=oldest_s,
                  worker_silent_after_s=settings.worker_silent_after_s, workers=listed,
                  sandbox={**isolation.to_dict(), "required": settings.sandbox_require_isolation})


def no_worker(queued: int, oldest_s: float | None, silent_s: float) -> str:
    waiting = (f"{queued} job{'s' if queued > 1 else ''} queued, the oldest for {oldest_s:.0f} s" if queued else
               "no job queued, but the next upload would wait")
    return (f"no worker heard from in the last {silent_s:g} s ({waiting}): start `league worker` (or `league serve` "
            f"without --no-worker) on this database")
