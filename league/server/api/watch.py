"""The API process watching itself: its row in the workers table (kind "api", with its version and
heartbeat, so that `league migrate` sees it), and the database's schema revision, checked at each
beat and after a database error. An API whose database was migrated under it (an upgrade that did
not stop it) answers 503 with what to do, instead of 500s on missing columns (`SchemaGuard`).
"""
from __future__ import annotations

import json
import logging

from fastapi import Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DBAPIError

from league.server.db.models import API_PROCESS
from league.server.jobs import registry
from league.server.jobs.worker import Periodic, schema_changed
from league.server.services import Services

log = logging.getLogger("league.server.api")


class ProcessWatch:
    """Registers this API process, beats every `worker_heartbeat_s`, and keeps `problem`: why this
    process must not answer (its schema is not the database's), or None."""

    def __init__(self, services: Services):
        self.services = services
        self.process_id: int | None = None
        self.problem: str | None = None
        self._beat = Periodic("league-api-beat", services.settings.worker_heartbeat_s, self.beat)

    def start(self) -> None:
        self.process_id = registry.register(self.services.sessions, API_PROCESS)
        self._beat.start()

    def stop(self) -> None:
        self._beat.stop()
        try:
            registry.unregister(self.services.sessions, self.process_id)
        except Exception:  # noqa: BLE001 - the database is gone (or its schema): the row expires
            log.warning("could not remove this API process from the workers table", exc_info=True)

    def beat(self) -> None:
        self.check()
        if self.problem is None:  # (a newer schema's table may not take our row)
            self.process_id = registry.beat(self.services.sessions, self.process_id,
                                            self.services.settings.worker_silent_after_s, API_PROCESS)

    def check(self) -> str | None:
        problem = schema_changed(self.services.sessions)
        if problem and problem != self.problem:
            log.error("API answering 503: %s", problem)
        self.problem = problem
        return problem


class SchemaGuard:
    """ASGI middleware: while the watch has a problem, every /api/ request but /api/health (which
    says why itself) is answered 503 with it."""

    def __init__(self, app, watch: ProcessWatch):
        self.app, self.watch = app, watch

    async def __call__(self, scope, receive, send):
        problem = self.watch.problem
        if problem is None or scope["type"] != "http" or not scope["path"].startswith("/api/") \
                or scope["path"] == "/api/health":
            return await self.app(scope, receive, send)
        body = json.dumps({"detail": problem}).encode()
        await send({"type": "http.response.start", "status": 503,
                    "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                                (b"retry-after", b"60")]})
        await send({"type": "http.response.body", "body": body})


async def database_error(request: Request, error: DBAPIError) -> JSONResponse:
    """A database error: if the schema changed under us, 503 with what to do; else a 500 as any error."""
    watch: ProcessWatch = request.app.state.watch
    try:
        problem = await run_in_threadpool(watch.check)
    except DBAPIError:  # the database does not answer at all: the first error is the one to report
        problem = None
    if problem is None:
        raise error
    return JSONResponse({"detail": problem}, status_code=503, headers={"Retry-After": "60"})
