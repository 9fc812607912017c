"""What the API works with, opened once per app: the settings, the database (engine and sessions), the
job queue, the store of model files and the clock. Routes reach them through the dependencies of
league.server.api.deps; a worker process opens its own."""
from __future__ import annotations

from dataclasses import dataclass, field

from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from league.server.core.clock import Clock
from league.server.core.config import Settings
from league.server.db.session import make_engine, make_sessionmaker
from league.server.jobs.queue import JobQueue
from league.server.storage import BlobStore


@dataclass
class Services:
    """The services of one league (`create_app` keeps it as `app.state.services`)."""

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    queue: JobQueue
    store: BlobStore
    clock: Clock = field(default_factory=Clock)  # what upload windows and due times are decided by


def open_services(settings: Settings, engine: Engine | None = None) -> Services:
    engine = engine or make_engine(settings.resolved_database_url)
    return Services(settings, engine, make_sessionmaker(engine), JobQueue(engine), BlobStore(settings.data_dir))
