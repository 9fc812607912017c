"""The queue is the jobs table; this module only wakes the workers that claim from it.

A job is queued by committing its row (status `queued`); workers claim rows straight from the
table (league.server.jobs.leases.claim_next), so nothing outside the database can lose a job: a
restore, an upgrade or a crash leaves every queued row where a worker finds it. A wake-up only
saves the wait for the next poll: on PostgreSQL `enqueue` sends a NOTIFY that every worker's
listener hears (`JobQueue.listen`); on SQLite, whose workers share the database's files on one
machine, the listener watches those files and wakes the job threads when a commit (an enqueue
among them) changed them; whenever either misses, idle job threads look again every `queue_poll_s`.
"""
from __future__ import annotations

import logging
import os
import threading
from pathlib import Path

from sqlalchemy import Engine, text
from sqlalchemy.engine import make_url

log = logging.getLogger("league.server.jobs")
CHANNEL = "league_jobs"  # PostgreSQL's notification channel
RECONNECT_S = 5.0  # a listener that lost its connection tries again after this long (polling meanwhile)
WATCH_S = 0.02  # how often a SQLite listener looks at the database's files (two stat calls)


class Wakeup:
    """Idle job threads of one process wait here until a job may be queued, or `timeout` passes.

    A generation counter rather than an event: a thread that found nothing at generation g sleeps
    only while the generation is still g, so a wake-up between its look and its wait is not lost."""

    def __init__(self):
        self._changed = threading.Condition()
        self.generation = 0

    def wake(self) -> None:
        with self._changed:
            self.generation += 1
            self._changed.notify_all()

    def wait(self, seen: int, timeout: float) -> None:
        with self._changed:
            self._changed.wait_for(lambda: self.generation != seen, timeout)


class JobQueue:
    """`enqueue(job_id)` after committing a queued job: wakes this process's job threads and, on
    PostgreSQL, every worker's (on SQLite the commit itself does, through `listen`). The job id is
    for logs only: workers claim the fairest queued job."""

    def __init__(self, engine: Engine):
        self.engine = engine
        self.wakeup = Wakeup()
        self.notifies = engine.dialect.name == "postgresql"
        self.watched = sqlite_files(engine)

    @property
    def listens(self) -> bool:
        """Whether `listen` has anything to listen to: NOTIFY, or the SQLite database's files."""
        return self.notifies or bool(self.watched)

    def enqueue(self, job_id: int) -> None:
        self.wakeup.wake()
        if not self.notifies:
            return
        try:
            with self.engine.connect() as connection:
                connection.execute(text("SELECT pg_notify(:channel, :job)"), {"channel": CHANNEL, "job": str(job_id)})
                connection.commit()
        except Exception:  # the job is queued all the same: the workers' next poll finds it
            log.warning("could not notify the workers of job %s; they will find it when they next look", job_id,
                        exc_info=True)

    def listen(self, stop: threading.Event) -> None:
        """Until `stop`, wake this process's job threads on every NOTIFY (PostgreSQL) or change of the
        database's files (SQLite): a thread's body."""
        if not self.notifies:
            return self._watch(stop)
        import psycopg

        url = make_url(self.engine.url).set(drivername="postgresql")
        while not stop.is_set():
            try:
                with psycopg.connect(url.render_as_string(hide_password=False), autocommit=True) as connection:
                    connection.execute(f"LISTEN {CHANNEL}")
                    self.wakeup.wake()  # anything queued while we were not listening
                    while not stop.is_set():
                        for _ in connection.notifies(timeout=1.0, stop_after=1):
                            self.wakeup.wake()
            except Exception as error:  # noqa: BLE001 - an outage: the poll carries on; try again later
                log.warning("job notifications: %s; polling only, listening again in %g s", error, RECONNECT_S)
                stop.wait(RECONNECT_S)

    def _watch(self, stop: threading.Event) -> None:
        """Wake the job threads whenever the SQLite database's files changed since the last look: any
        commit of any process on this machine (the API's enqueue, another worker's) changes the
        write-ahead log or, without one, the database file; reads change neither."""
        last = files_signature(self.watched)
        self.wakeup.wake()  # anything committed before that look
        while not stop.wait(WATCH_S):
            now = files_signature(self.watched)
            if now != last:
                last = now
                self.wakeup.wake()


def sqlite_files(engine: Engine) -> tuple[Path, ...]:
    """The files a commit to this SQLite database changes (the database and its write-ahead log);
    () for another backend or a database in memory."""
    url = make_url(engine.url)
    if url.get_backend_name() != "sqlite" or url.database in (None, "", ":memory:"):
        return ()
    database = Path(url.database).resolve()
    return database, database.with_name(database.name + "-wal")


def files_signature(paths: tuple[Path, ...]) -> tuple:
    """What a commit changes of these files: each one's inode, size and modification time (None: absent)."""
    signature = []
    for path in paths:
        try:
            status = os.stat(path)
        except OSError:
            signature.append(None)
        else:
            signature.append((status.st_ino, status.st_size, status.st_mtime_ns))
    return tuple(signature)
