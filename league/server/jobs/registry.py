"""The workers table: which league processes run, with their version and heartbeat. Each worker and
each API process inserts its row at start, beats every `worker_heartbeat_s` and deletes its row when
it stops; the rows of processes that died (killed with -9, a lost machine) expire after
EXPIRE_SILENCES silence windows, so their metric series go away. /api/health counts the workers;
`league migrate` refuses while processes of another version run (`refuse_other_versions`).
"""
from __future__ import annotations

import os
import socket
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone

from sqlalchemy import Connection, MetaData, Table, delete, inspect, select, update
from sqlalchemy.orm import Session, sessionmaker

import league
from league.server.core.clock import utcnow
from league.server.db.models import WORKER_PROCESS, WorkerProcess
from league.server.db.session import DatabaseError

EXPIRE_SILENCES = 2  # a process silent for this many silence windows died without removing its row


def expiry(silent_after_s: float) -> timedelta:
    return timedelta(seconds=EXPIRE_SILENCES * silent_after_s)


def register(sessions: sessionmaker[Session], kind: str = WORKER_PROCESS) -> int:
    """This process's row; its id."""
    with sessions.begin() as session:
        row = WorkerProcess(kind=kind, host=socket.gethostname()[:255], pid=os.getpid(),
                            version=league.__version__[:50])
        session.add(row)
        session.flush()
        return row.id


def beat(sessions: sessionmaker[Session], process_id: int, silent_after_s: float, kind: str = WORKER_PROCESS) -> int:
    """Say this process is alive and expire the rows of dead ones; returns its id (a new row if its own
    was removed: a restore, or this process was stopped longer than the expiry)."""
    with sessions.begin() as session:
        session.execute(delete(WorkerProcess).where(WorkerProcess.heartbeat_at < utcnow() - expiry(silent_after_s)))
        if session.execute(update(WorkerProcess).where(WorkerProcess.id == process_id)
                           .values(heartbeat_at=utcnow())).rowcount:
            return process_id
    return register(sessions, kind)


def unregister(sessions: sessionmaker[Session], process_id: int) -> None:
    with sessions.begin() as session:
        session.execute(delete(WorkerProcess).where(WorkerProcess.id == process_id))


def forget_all(session: Session) -> None:
    """A restored database's processes are not running here."""
    session.execute(delete(WorkerProcess))


def workers(session: Session) -> list[WorkerProcess]:
    """The registered workers (not expired), the longest-running first."""
    return list(session.scalars(select(WorkerProcess).where(WorkerProcess.kind == WORKER_PROCESS)
                                .order_by(WorkerProcess.started_at, WorkerProcess.id)))


def is_alive(process: WorkerProcess, silent_after_s: float, now: datetime | None = None) -> bool:
    return process.heartbeat_at >= (now or utcnow()) - timedelta(seconds=silent_after_s)


def live_workers(session: Session, silent_after_s: float, now: datetime | None = None) -> list[WorkerProcess]:
    """The workers heard from in the last `silent_after_s` seconds, the longest-running first."""
    return [worker for worker in workers(session) if is_alive(worker, silent_after_s, now)]


# --------------------------------------------------------------------------- the guard of `league migrate`


@dataclass(frozen=True)
class Registered:
    """A registered process, as any schema since 0014 lists it (`kind` since 0022: workers before)."""

    kind: str
    host: str
    pid: int
    version: str
    heartbeat_at: datetime

    def describe(self, now: datetime) -> str:
        return (f"{self.kind} {self.version} on {self.host}, pid {self.pid}, last heartbeat "
                f"{self.heartbeat_at:%Y-%m-%d %H:%M:%S} UTC ({(now - self.heartbeat_at).total_seconds():.0f} s ago)")


def registered_elsewhere(connection: Connection, version: str | None = None) -> list[Registered]:
    """The processes of a version other than `version` (default: this one) the database lists, read
    whatever its schema (releases before 0.2.0 registered their workers only, from revision 0014)."""
    if not inspect(connection).has_table("workers"):
        return []
    table = Table("workers", MetaData(), autoload_with=connection)
    kind = table.c.kind if "kind" in table.c else None
    rows = connection.execute(select(table.c.host, table.c.pid, table.c.version, table.c.heartbeat_at,
                                     *([kind] if kind is not None else []))
                              .where(table.c.version != (version or league.__version__))
                              .order_by(table.c.heartbeat_at.desc()))
    return [Registered(row[4] if kind is not None else WORKER_PROCESS, row[0], row[1], row[2],
                       row[3].replace(tzinfo=timezone.utc))  # (stored naive UTC: models.UTCDateTime)
            for row in rows]


def refuse_other_versions(connection: Connection, silent_after_s: float, force: bool,
                          now: datetime | None = None) -> None:
    """Raise DatabaseError naming the processes of another version: the live ones (beat within
    `silent_after_s`) must be stopped; the silent ones are forgotten with `force` (they died; their
    rows would expire by themselves after EXPIRE_SILENCES windows)."""
    now = now or utcnow()
    others = registered_elsewhere(connection)
    alive = [p for p in others if p.heartbeat_at >= now - timedelta(seconds=silent_after_s)]
    silent = [p for p in others if p not in alive]
    if force and silent:
        table = Table("workers", MetaData(), autoload_with=connection)
        silent_since = (now - timedelta(seconds=silent_after_s)).astimezone(timezone.utc).replace(tzinfo=None)
        connection.execute(delete(table).where(table.c.version != league.__version__,
                                               table.c.heartbeat_at < silent_since))
        connection.commit()
        silent = []
    if not alive and not silent:
        return
    named = [f"alive: {p.describe(now)}" for p in alive] + [f"silent: {p.describe(now)}" for p in silent]
    todo = ["Stop them first (every API and worker of the old version; with Docker: `docker compose stop`)"] \
        if alive else []
    if silent:
        todo.append(f"{'the' if alive else 'The'} silent ones have not beaten for over {silent_after_s:g} s: if "
                    f"they are dead, run again with --force to forget them")
    raise DatabaseError(f"processes of another version than this one ({league.__version__}) use this database, "
                           f"and migrating under them would break them: {'; '.join(named)}. {'; '.join(todo)}.")
