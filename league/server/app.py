"""The FastAPI application, the server's one entry module: `create_app(settings)` builds it; nothing
else happens at import. `league serve` (league.server.cli) migrates the database, builds the app and
starts a worker beside it; `uvicorn --factory league.server.app:create_app` serves the API alone, with
the environment's settings, on a database `league migrate` brought up to date.
"""
from __future__ import annotations

import gc
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse
from fastapi_offline import FastAPIOffline
from sqlalchemy.exc import DBAPIError
from starlette.exceptions import HTTPException as StarletteHTTPException

import league
from league.server.api.cache import ResponseCache
from league.server.api.limits import KB, BodyLimits, Limit
from league.server.api.routes import api_router
from league.server.api.routes.submissions import StatusAnswers
from league.server.api.routes.tracks import MAX_TRACK_BYTES
from league.server.api.watch import ProcessWatch, SchemaGuard, database_error
from league.server import metrics
from league.server.bootstrap import bootstrap
from league.server.core.config import Settings, load_settings
from league.server.course.roster import MAX_ROSTER_BYTES
from league.server.db.session import check_schema, revision_of
from league.server.jobs.runner import close_due_now
from league.server.jobs.worker import sweep_store
from league.server.pages import mount_web
from league.server.sandbox.process import ForkServer, sandbox_isolation
from league.server.services import Services, open_services

MULTIPART_SLACK = 64 * 1024  # bytes of multipart framing and form fields allowed on top of the file


def prepare_league(services: Services) -> None:
    """Check the schema (`league serve` or `league migrate` brought it up to date), create the store,
    register the baselines on first start (idempotent)."""
    with services.engine.connect() as connection:
        check_schema(revision_of(connection))
    services.store.ensure()
    bootstrap(services.settings, services.sessions, services.queue, services.store)
    catch_up(services)
    sweep_store(services.sessions, services.store)
    sandbox_isolation(services.settings.sandbox_uid_base)  # logged, and shown by /api/health
    ForkServer.release_this_thread()  # (the probe's: the API runs no sandbox)


def catch_up(services: Services) -> list[int]:
    """Freeze and queue the private tests of the due times that passed while the league was down (the
    reaper's passes do it while it runs)."""
    return close_due_now(services.sessions, services.queue, max_attempts=services.settings.max_job_attempts,
                         now=services.clock.now())


@asynccontextmanager
async def lifespan(app: FastAPI):
    await run_in_threadpool(prepare_league, app.state.services)
    await run_in_threadpool(app.state.watch.start)
    # The startup's objects (modules, the app, its routes and schemas) live as long as the process: out of
    # the collector's sight, a full collection no longer walks them in the middle of answers (halves the
    # status answers' p99 under load, bench_server (d))
    gc.freeze()
    yield
    await run_in_threadpool(app.state.watch.stop)
    app.state.services.engine.dispose()


def create_app(settings: Settings | None = None, services: Services | None = None) -> FastAPI:
    settings = settings or load_settings()
    services = services or open_services(settings)
    app = FastAPIOffline(title="MicroRacer League", version=league.__version__, lifespan=lifespan,  # /docs: no CDN
                         description="Upload TorchScript or ONNX agents; they are validated in a sandbox and "
                                     "evaluated on the course's tracks.")
    # what the routes' dependencies (league.server.api.deps) hand them
    app.state.services = services
    app.state.cache = ResponseCache(settings.public_cache_s, settings.public_cache_max_age_s)
    app.state.watch = ProcessWatch(services)  # this process in the workers table; the schema under it
    app.include_router(api_router, prefix="/api")
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(DBAPIError, database_error)
    mount_web(app, settings)
    app.add_middleware(StatusAnswers, services=services)  # inside the metrics' timer (installed next)
    metrics.install(app, services.sessions, settings.worker_silent_after_s)
    app.add_middleware(BodyLimits, default=Limit.of(64 * KB), limits=body_limits(settings),
                       read_timeout_s=settings.request_body_timeout_s)
    app.add_middleware(SchemaGuard, watch=app.state.watch)
    return app


def body_limits(settings: Settings) -> dict[tuple[str, str], Limit]:
    """The routes that take more than a small JSON body (multipart framing counted on top of files)."""
    return {
        ("POST", "/api/submissions"): Limit.of(settings.max_upload_bytes + MULTIPART_SLACK, "file",
                                               shown=settings.max_upload_bytes),
        ("POST", "/api/users/roster"): Limit.of(MAX_ROSTER_BYTES + MULTIPART_SLACK, "roster", shown=MAX_ROSTER_BYTES),
        ("POST", "/api/tracks/geometry"): Limit.of(MAX_TRACK_BYTES, "track"),
    }


async def _http_error(request: Request, error: StarletteHTTPException) -> JSONResponse:
    return JSONResponse({"detail": error.detail}, status_code=error.status_code,
                        headers=getattr(error, "headers", None))


async def _validation_error(request: Request, error: RequestValidationError) -> JSONResponse:
    """Invalid input: one sentence, as every other error (docs/CONTRACT.md), not pydantic's list."""
    return JSONResponse({"detail": validation_text(error.errors())}, status_code=422)


def validation_text(errors) -> str:
    """"body.points: List should have at least 1 item after validation, not 0; ..." (where, then what)."""
    parts = []
    for item in errors:
        where = ".".join(str(part) for part in item.get("loc", ()) if part != "body")
        parts.append(f"{where}: {item.get('msg', 'invalid')}" if where else item.get("msg", "invalid"))
    return "; ".join(parts) or "invalid request"
