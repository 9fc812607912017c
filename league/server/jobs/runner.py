"""Running one job: claim it, keep its lease alive while its handler works, record the outcome.

A handler (league.server.jobs.handlers) is one kind of job: `begin` and `finish` run inside the
lease transactions (league.server.jobs.leases), `run` does the slow work with no transaction
open. A worker process runs jobs on several threads, each placed on its CPUs first
(league.server.jobs.placement).
"""
from __future__ import annotations

import logging
import os
import socket
import threading
import time
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Protocol

from sqlalchemy.exc import IntegrityError, OperationalError
from sqlalchemy.orm import Session, sessionmaker

from league.server.core.clock import utcnow
from league.server.core.config import Settings
from league.server.core.logs import job_outcome, log_job
from league.server.course.assignments import close_due
from league.server.db import crud
from league.server.db.models import Job, Submission
from league.server.jobs import leases
from league.server.jobs.placement import Placement
from league.server.jobs.queue import JobQueue
from league.server.sandbox.child import set_autogroup_nice
from league.server.sandbox.process import ForkServer
from league.server.storage import BlobStore

log = logging.getLogger("league.server.jobs")


class JobCannotSucceed(Exception):
    """Raised by a handler when trying again cannot help (the job fails at once, with this reason)."""


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


@dataclass
class WorkerContext:
    settings: Settings
    sessions: sessionmaker[Session]
    queue: JobQueue
    store: BlobStore
    handlers: Mapping[str, JobHandler]  # job kind -> handler
    active: dict[int, JobRun] = field(default_factory=dict)  # jobs this process is running
    placement: Placement | None = None  # CPUs of job threads and their sandboxes (None: left to the OS)


@dataclass
class JobRun:
    """What a handler gets while it works: the job as claimed, and a flag raised if the lease is lost."""

    context: WorkerContext
    job: Job
    attempt_id: str
    lease_lost: threading.Event = field(default_factory=threading.Event)

    def submission(self) -> Submission:
        """The job's submission (validation and evaluation jobs)."""
        with self.context.sessions() as session:
            return session.get(Submission, self.job.submission_id)

    def model_file(self, submission: Submission) -> Path:
        """The submission's file in this worker's store, fetched from the database on first use here
        (a worker on another machine shares only the database)."""
        store = self.context.store
        path = store.path(submission.sha256)
        if path.exists():
            return path
        with self.context.sessions() as session:
            data = crud.blob_data(session, sha256=submission.sha256)
        if data is None:
            raise JobCannotSucceed(f"the file of submission {submission.id} is no longer kept")
        return store.write_verified(submission.sha256, data)


def new_attempt_id() -> str:
    return f"{socket.gethostname()}/{os.getpid()}/{uuid.uuid4().hex[:8]}"


def run_next(context: WorkerContext) -> bool:
    """Claim the fairest queued job, run it with heartbeats, record the outcome; False if none was queued."""
    attempt_id = new_attempt_id()
    job = leases.claim_next(context.sessions, context.handlers, attempt_id=attempt_id)
    if job is None:
        return False
    place_thread(context, context.handlers[job.kind])
    run = JobRun(context, job, attempt_id)
    context.active[job.id] = run
    try:
        _work(run)
    finally:
        context.active.pop(job.id, None)
    return True


def prepare_job_thread(settings: Settings) -> None:
    """When a job thread starts (in that thread): its priority, then its fork
    server, which prepares every runtime before the first job, at that priority."""
    lower_thread_priority(settings.job_nice)
    ForkServer.prepare_this_thread()


def lower_thread_priority(nice: int) -> None:
    """Give this thread (Linux keeps a nice value per thread) and the sandboxes it starts a lower
    CPU priority than the API's, so that status and leaderboard requests stay fast under load."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
    except OSError:  # not allowed to lower it back (not root, nice already higher): keep what we have
        pass


def lower_session_priority(nice: int) -> None:
    """Linux schedules each session as one group (its autogroup), which a thread's nice value does not
    lower: a worker that leads its own session (serve's child, a systemd service) puts its whole group
    at `nice`, or the API's session would share the CPU with it as an equal. A worker typed in a shell
    shares the shell's session, which is not ours to lower."""
    if os.getsid(0) == os.getpid():
        set_autogroup_nice(nice)


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
    context, job, started = run.context, run.job, time.monotonic()
    with Heartbeat(context.sessions, run, context.settings.heartbeat_interval_s):
        try:
            outcome = context.handlers[job.kind].run(run)
        except JobCannotSucceed as error:
            leases.fail(context.sessions, context.handlers, job_id=job.id, attempt_id=run.attempt_id,
                        reason=str(error))
            log_job(job, "failed", started, str(error))
            return
        except Exception as error:  # a bug or an outage: retried, then failed with the reason
            log.exception("job %s (%s) attempt %s failed", job.id, job.kind, job.attempts)
            retried = leases.retry_or_fail(context.sessions, context.handlers, job_id=job.id,
                                           attempt_id=run.attempt_id, reason=f"{type(error).__name__}: {error}")
            log_job(job, "retried" if retried else "failed", started, f"{type(error).__name__}: {error}")
            if retried:
                context.queue.enqueue(job.id)
            return
    follow_ups = leases.complete(context.sessions, context.handlers, job_id=job.id, attempt_id=run.attempt_id,
                                 outcome=outcome)
    log_job(job, job_outcome(outcome), started, getattr(outcome, "error", None))
    for follow_up in follow_ups:
        context.queue.enqueue(follow_up)


def release_active(context: WorkerContext) -> list[int]:
    """A worker shutting down hands its running jobs back to the queue at once (no lease timeout to wait)."""
    released = []
    for job_id, run in list(context.active.items()):
        run.lease_lost.set()  # the job stops, and will not write its results
        if leases.hand_back(context.sessions, job_id=job_id, attempt_id=run.attempt_id, reason="its worker shut down"):
            released.append(job_id)
    for job_id in released:
        context.queue.enqueue(job_id)
    return released


def reap(context: WorkerContext) -> list[int]:
    """One reaper pass (league.server.jobs.leases.reap), waking the workers for what it re-queued; and
    the private tests of the due times that passed (league.server.course.assignments.close_due)."""
    requeued = leases.reap(context.sessions, context.handlers, lease_timeout_s=context.settings.lease_timeout_s)
    for job_id in requeued:
        context.queue.enqueue(job_id)
    return requeued + close_due_now(context.sessions, context.queue, max_attempts=context.settings.max_job_attempts)


def close_due_now(sessions: sessionmaker[Session], queue: JobQueue, *, max_attempts: int,
                  now: datetime | None = None) -> list[int]:
    """Freeze the finals that came due and send their private tests to the queue. Another process
    doing the same at the same moment (a worker's reaper, the API starting) may win a student's row
    first: this pass then gives way, and the next one finds it done."""
    try:
        with sessions.begin() as session:
            job_ids = close_due(session, now=now or utcnow(), max_attempts=max_attempts)
    except (IntegrityError, OperationalError) as error:
        log.warning("due-time pass gave way to another process: %s", error)
        return []
    for job_id in job_ids:
        queue.enqueue(job_id)
    return job_ids


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
                held = leases.heartbeat(self.sessions, job_id=self.run.job.id, attempt_id=self.run.attempt_id)
            except Exception:  # a database hiccup: try again next beat; the lease timeout is several beats
                log.exception("job %s: heartbeat failed", self.run.job.id)
                continue
            if not held:
                log.warning("job %s: lease lost (re-queued by the reaper?); stopping", self.run.job.id)
                self.run.lease_lost.set()
                return
