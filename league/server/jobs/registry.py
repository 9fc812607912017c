"""The workers table: which worker processes are alive, so that /api/health can say whether the
queued jobs have anyone to run them. Each worker inserts its row at start, beats every
`worker_heartbeat_s` and deletes the row when it stops; the rows of workers that died are pruned.
"""
from __future__ import annotations

import os
import socket
from datetime import datetime, timedelta

from sqlalchemy import delete, select, update
from sqlalchemy.orm import Session, sessionmaker

import league
from league.server.db.models import WorkerProcess, utcnow

FORGET_AFTER = timedelta(days=1)  # a worker silent this long died without removing its row


def register(sessions: sessionmaker[Session]) -> int:
    """This process's row; its id."""
    with sessions.begin() as session:
        row = WorkerProcess(host=socket.gethostname()[:255], pid=os.getpid(), version=league.__version__[:50])
        session.add(row)
        session.flush()
        return row.id


def beat(sessions: sessionmaker[Session], worker_id: int) -> int:
    """Say this worker is alive; returns its id (a new row if its own was removed: a restore, a prune)."""
    with sessions.begin() as session:
        session.execute(delete(WorkerProcess).where(WorkerProcess.heartbeat_at < utcnow() - FORGET_AFTER))
        if session.execute(update(WorkerProcess).where(WorkerProcess.id == worker_id)
                           .values(heartbeat_at=utcnow())).rowcount:
            return worker_id
    return register(sessions)


def unregister(sessions: sessionmaker[Session], worker_id: int) -> None:
    with sessions.begin() as session:
        session.execute(delete(WorkerProcess).where(WorkerProcess.id == worker_id))


def forget_all(session: Session) -> None:
    """A restored database's workers are not running here."""
    session.execute(delete(WorkerProcess))


def live_workers(session: Session, silent_after_s: float, now: datetime | None = None) -> list[WorkerProcess]:
    """The workers heard from in the last `silent_after_s` seconds, the longest-running first."""
    since = (now or utcnow()) - timedelta(seconds=silent_after_s)
    return list(session.scalars(select(WorkerProcess).where(WorkerProcess.heartbeat_at >= since)
                                .order_by(WorkerProcess.started_at, WorkerProcess.id)))
