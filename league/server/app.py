"""The FastAPI application: `create_app(settings)` builds it; nothing else happens at import."""
from __future__ import annotations

from contextlib import asynccontextmanager
from dataclasses import dataclass

from league.server.api.routes.pages import mount_web
from fastapi import FastAPI, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker
from starlette.exceptions import HTTPException as StarletteHTTPException

import league
from league.server.api.cache import ResponseCache
from league.server.api.main import api_router, upload_router
from league.server.bootstrap import bootstrap
from league.server.config import MB, Settings
from league.server.db.session import make_engine, make_sessionmaker, migrate
from league.server.storage import BlobStore
from league.server.taskqueue import JobQueue, build_queue

MULTIPART_SLACK = 64 * 1024  # bytes of multipart framing and form fields allowed on top of the file


@dataclass
class League:
    """What the app and an embedded worker share."""

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    queue: JobQueue
    store: BlobStore


def open_league(settings: Settings) -> League:
    engine = make_engine(settings.resolved_database_url)
    return League(settings, engine, make_sessionmaker(engine), build_queue(settings), BlobStore(settings.data_dir))


def prepare_league(league_: League) -> None:
    """Migrate the database, create the store, register the baselines on first start (idempotent)."""
    migrate(league_.engine)
    league_.store.ensure()
    bootstrap(league_.settings, league_.sessions, league_.queue, league_.store)


@asynccontextmanager
async def lifespan(app: FastAPI):
    await run_in_threadpool(prepare_league, app.state.league)
    yield
    app.state.league.engine.dispose()


def create_app(settings: Settings | None = None, league_: League | None = None) -> FastAPI:
    settings = settings or Settings()
    league_ = league_ or open_league(settings)
    app = FastAPI(title="MicroRacer League", version=league.__version__, lifespan=lifespan,
                  description="Upload TorchScript or ONNX agents; they are validated in a sandbox and "
                              "evaluated on the course's tracks.")
    app.state.league, app.state.settings, app.state.sessions = league_, settings, league_.sessions
    app.state.queue, app.state.store = league_.queue, league_.store
    app.state.cache = ResponseCache(settings.public_cache_s)
    app.include_router(api_router, prefix="/api")
    app.include_router(upload_router, prefix="/api", max_body_size=settings.max_upload_bytes + MULTIPART_SLACK)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    mount_web(app)
    return app


async def _http_error(request: Request, error: StarletteHTTPException) -> JSONResponse:
    detail = error.detail
    if error.status_code == 413 and detail == "Content Too Large":  # the framework's body limit, said plainly
        detail = f"file too large: the limit is {request.app.state.settings.max_upload_bytes / MB:g} MB"
    return JSONResponse({"detail": detail}, status_code=error.status_code, headers=getattr(error, "headers", None))
