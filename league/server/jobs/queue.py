"""The task queue: Huey, on SQLite (embedded default) or Redis (workers on several machines).

Messages carry only a job id; the job, its status and its lease are in the database, so a lost
message or a dead consumer never loses work (see league.server.jobs.leases).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from huey import RedisHuey, SqliteHuey
from huey.api import Huey
from sqlalchemy.engine import make_url

from league.server.config import Settings
from league.server.db.session import create_private_file


class JobQueue:
    """Huey plus the one task it runs: `run_job(job_id)`, executed by whoever set `runner`."""

    def __init__(self, huey: Huey):
        self.huey = huey
        self.runner: Callable[[int], None] | None = None  # set in worker processes only
        self._task = huey.task(retries=0, name="run_job")(self._run)

    def _run(self, job_id: int) -> None:
        if self.runner is None:
            raise RuntimeError("this process has no job runner (it is not a worker)")
        self.runner(job_id)

    def enqueue(self, job_id: int) -> None:
        self._task(job_id)

    def pending(self) -> int:
        return self.huey.pending_count()

    def flush(self) -> None:
        self.huey.flush()


def build_queue(settings: Settings) -> JobQueue:
    return JobQueue(_build_huey(settings.resolved_queue_url, settings.queue_name))


def _build_huey(url: str, name: str) -> Huey:
    if url.startswith(("redis://", "rediss://", "unix://")):
        return RedisHuey(name=name, url=url, results=False)
    parsed = make_url(url)
    if parsed.get_backend_name() != "sqlite" or not parsed.database:
        raise ValueError(f"queue_url must be redis://... or sqlite:///path, got {url!r}")
    create_private_file(Path(parsed.database))
    return SqliteHuey(name=name, filename=parsed.database, results=False)
