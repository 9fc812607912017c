"""Jobs with leases in the database: a job is never stuck, and its results are written once.

As in fishtest, a worker that takes a task keeps it alive with heartbeats and a scavenger
reclaims tasks whose worker went quiet. Here:

* claim: `queued -> running` by a conditional UPDATE (one worker wins), with a fresh attempt id;
* heartbeat: a thread refreshes `heartbeat_at` while the job runs; if the lease was taken away,
  the job is told to stop (`lease_lost`);
* complete: the results are written in the transaction that moves `running -> done`, and only
  if this attempt still holds the lease -- so a re-run job is counted once;
* reap: running jobs whose heartbeat is older than `lease_timeout` go back to the queue (or are
  failed for good with their reason after `max_attempts`); queued jobs whose message may have
  been lost are sent again (a duplicate message finds the job taken and does nothing).

The queue (Huey) only carries job ids; every status users see is in the database.
"""
from __future__ import annotations

import logging
import os
import socket
import threading
import uuid
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any, Protocol

from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from league.server.config import Settings
from league.server.db.models import DONE, FAILED, QUEUED, RUNNING, Job, utcnow
from league.server.placement import Placement
from league.server.storage import BlobStore
from league.server.taskqueue import JobQueue

log = logging.getLogger("league.server.jobs")


@dataclass
class WorkerContext:
    settings: Settings
    sessions: sessionmaker[Session]
    queue: JobQueue
    store: BlobStore
    active: dict[int, JobRun] = field(default_factory=dict)  # jobs this process is running
    placement: Placement | None = None  # CPUs of job threads and their sandboxes (None: left to the OS)


@dataclass
class JobRun:
    """What a handler gets while it works: the job as claimed, and a flag raised if the lease is lost."""

    context: WorkerContext
    job: Job
    attempt_id: str
    lease_lost: threading.Event = field(default_factory=threading.Event)


class JobHandler(Protocol):
    parallel_sandboxes: bool  # its sandboxes work at the same time (a race), or one at a time

    def begin(self, session: Session, job: Job) -> None:
        """In the claim's transaction: show the subject as in progress."""

    def run(self, run: JobRun) -> Any:
        """The work, outside any transaction; raising means an infrastructure failure (retried)."""

    def finish(self, session: Session, job: Job, outcome: Any) -> list[int]:
        """In the completing transaction: write the outcome; return follow-up job ids to enqueue."""

    def give_up(self, session: Session, job: Job, reason: str) -> None:
        """In the failing transaction: the job failed for good, show why."""


HANDLERS: dict[str, JobHandler] = {}


def register_handler(kind: str, handler: JobHandler) -> None:
    HANDLERS[kind] = handler


def new_attempt_id() -> str:
    return f"{socket.gethostname()}/{os.getpid()}/{uuid.uuid4().hex[:8]}"


# --------------------------------------------------------------------------- one job


def run_job(context: WorkerContext, job_id: int) -> None:
    """Execute one queue message: claim the job, run it with heartbeats, record the outcome."""
    lower_thread_priority(context.settings.job_nice)
    attempt_id = new_attempt_id()
    job = claim(context.sessions, job_id=job_id, attempt_id=attempt_id)
    if job is None:
        return  # done, failed, or running elsewhere: a duplicate message
    place_thread(context, HANDLERS[job.kind])
    run = JobRun(context, job, attempt_id)
    context.active[job.id] = run
    try:
        _work(run)
    finally:
        context.active.pop(job.id, None)


def lower_thread_priority(nice: int) -> None:
    """Give this thread (Linux keeps a nice value per thread) and the sandboxes it starts a lower
    CPU priority than the API's, so that status and leaderboard requests stay fast under load."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
    except OSError:  # not allowed to lower it back (not root, nice already higher): keep what we have
        pass


def place_thread(context: WorkerContext, handler: JobHandler) -> None:
    """Put this thread (and the sandboxes it starts) on its CPUs for the job."""
    if context.placement is None:
        return
    try:
        cpus = context.placement.place(parallel=getattr(handler, "parallel_sandboxes", False))
    except OSError as error:  # placement is for speed only: the job runs anyway
        log.warning("could not place job thread on CPUs: %s", error)
        return
    log.debug("job thread on CPUs %s", ",".join(map(str, cpus)))


def _work(run: JobRun) -> None:
    context, job = run.context, run.job
    with Heartbeat(context.sessions, run, context.settings.heartbeat_interval_s):
        try:
            outcome = HANDLERS[job.kind].run(run)
        except Exception as error:  # a bug or an outage: retried, then failed with the reason
            log.exception("job %s (%s) attempt %s failed", job.id, job.kind, job.attempts)
            _retry_or_fail(context, job_id=job.id, attempt_id=run.attempt_id, reason=f"{type(error).__name__}: {error}")
            return
    for follow_up in complete(context.sessions, job_id=job.id, attempt_id=run.attempt_id, outcome=outcome):
        context.queue.enqueue(follow_up)


def release_active(context: WorkerContext) -> list[int]:
    """A worker shutting down hands its running jobs back to the queue at once (no lease timeout to wait)."""
    released = []
    for job_id, run in list(context.active.items()):
        run.lease_lost.set()  # the job stops, and will not write its results
        with context.sessions.begin() as session:
            if _take_lease_for(session, job_id, run.attempt_id, QUEUED, worker_id=None, enqueued_at=utcnow(),
                               error="its worker shut down"):
                released.append(job_id)
    for job_id in released:
        context.queue.enqueue(job_id)
    return released


def claim(sessions: sessionmaker[Session], *, job_id: int, attempt_id: str) -> Job | None:
    now = utcnow()
    with sessions.begin() as session:
        taken = session.execute(
            update(Job).where(Job.id == job_id, Job.status == QUEUED)
            .values(status=RUNNING, worker_id=attempt_id, attempts=Job.attempts + 1, started_at=now, heartbeat_at=now)
        ).rowcount
        if not taken:
            return None
        job = session.get(Job, job_id, populate_existing=True)
        HANDLERS[job.kind].begin(session, job)
        return job


def heartbeat(sessions: sessionmaker[Session], *, job_id: int, attempt_id: str) -> bool:
    """Refresh the lease; False if this attempt no longer holds it."""
    with sessions.begin() as session:
        return bool(session.execute(
            update(Job).where(Job.id == job_id, Job.status == RUNNING, Job.worker_id == attempt_id)
            .values(heartbeat_at=utcnow())
        ).rowcount)


def complete(sessions: sessionmaker[Session], *, job_id: int, attempt_id: str, outcome: Any) -> list[int]:
    with sessions.begin() as session:
        if not _take_lease_for(session, job_id, attempt_id, DONE):
            log.warning("job %s: lease lost before completion; its results are discarded", job_id)
            return []
        job = session.get(Job, job_id, populate_existing=True)
        return HANDLERS[job.kind].finish(session, job, outcome)


def _take_lease_for(session: Session, job_id: int, attempt_id: str, status: str, **values: Any) -> bool:
    """Move this attempt's running job to `status`; row-locks it until the transaction ends."""
    return bool(session.execute(
        update(Job).where(Job.id == job_id, Job.status == RUNNING, Job.worker_id == attempt_id)
        .values(status=status, finished_at=utcnow() if status in (DONE, FAILED) else None, **values)
    ).rowcount)


def _retry_or_fail(context: WorkerContext, *, job_id: int, attempt_id: str, reason: str) -> None:
    with context.sessions.begin() as session:
        job = session.get(Job, job_id, populate_existing=True)
        if job.attempts >= job.max_attempts:
            if _take_lease_for(session, job_id, attempt_id, FAILED, error=reason):
                HANDLERS[job.kind].give_up(session, job, reason)
            return
        requeued = _take_lease_for(session, job_id, attempt_id, QUEUED, error=reason, worker_id=None,
                                   enqueued_at=utcnow())
    if requeued:
        context.queue.enqueue(job_id)


class Heartbeat:
    """A thread that keeps a running job's lease fresh (a context manager around the work)."""

    def __init__(self, sessions: sessionmaker[Session], run: JobRun, interval_s: float):
        self.sessions, self.run, self.interval_s = sessions, run, interval_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name=f"heartbeat-{run.job.id}", daemon=True)

    def __enter__(self) -> Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc_info) -> None:
        self._stop.set()
        self._thread.join()

    def _beat(self) -> None:
        while not self._stop.wait(self.interval_s):
            try:
                held = heartbeat(self.sessions, job_id=self.run.job.id, attempt_id=self.run.attempt_id)
            except Exception:  # a database hiccup: try again next beat; the lease timeout is several beats
                log.exception("job %s: heartbeat failed", self.run.job.id)
                continue
            if not held:
                log.warning("job %s: lease lost (re-queued by the reaper?); stopping", self.run.job.id)
                self.run.lease_lost.set()
                return


# --------------------------------------------------------------------------- reaper


def reap(context: WorkerContext, now: datetime | None = None) -> list[int]:
    """Re-queue running jobs whose worker stopped heart-beating and re-send long-queued ones.

    Returns the ids sent to the queue. Safe to run in every worker at once: each change is a
    conditional UPDATE that only one of them can make.
    """
    now = now or utcnow()
    settings = context.settings
    stale_before = now - timedelta(seconds=settings.lease_timeout_s)
    resend_before = now - timedelta(seconds=settings.requeue_queued_after_s)
    with context.sessions() as session:
        stale = list(session.scalars(select(Job.id).where(Job.status == RUNNING, Job.heartbeat_at < stale_before)))
        lost = list(session.scalars(select(Job.id).where(Job.status == QUEUED, Job.enqueued_at < resend_before)))
    sent = [job_id for job_id in stale if _release_stale(context, job_id, stale_before, now)]
    sent += [job_id for job_id in lost if _mark_resent(context, job_id, resend_before, now)]
    for job_id in sent:
        context.queue.enqueue(job_id)
    return sent


def _release_stale(context: WorkerContext, job_id: int, stale_before: datetime, now: datetime) -> bool:
    still_stale = (Job.id == job_id, Job.status == RUNNING, Job.heartbeat_at < stale_before)
    with context.sessions.begin() as session:
        job = session.get(Job, job_id)
        reason = f"its worker ({job.worker_id}) stopped heart-beating"
        if job.attempts >= job.max_attempts:
            failed = session.execute(update(Job).where(*still_stale).values(
                status=FAILED, error=f"gave up after {job.attempts} attempts: {reason}", finished_at=now)).rowcount
            if failed:
                HANDLERS[job.kind].give_up(session, job, f"gave up after {job.attempts} attempts: {reason}")
            return False
        requeued = session.execute(update(Job).where(*still_stale).values(
            status=QUEUED, worker_id=None, error=reason, enqueued_at=now)).rowcount
    if requeued:
        log.warning("job %s re-queued: %s", job_id, reason)
    return bool(requeued)


def _mark_resent(context: WorkerContext, job_id: int, resend_before: datetime, now: datetime) -> bool:
    with context.sessions.begin() as session:
        return bool(session.execute(update(Job).where(
            Job.id == job_id, Job.status == QUEUED, Job.enqueued_at < resend_before).values(enqueued_at=now)).rowcount)
