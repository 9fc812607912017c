"""Leases in the database: a job is never stuck, and its results are written once.

As in fishtest, a worker that takes a task keeps it alive with heartbeats and a scavenger
reclaims tasks whose worker went quiet. Here:

* claim: the fairest queued job (normal priority first, owners in turn, validations first) goes
  `queued -> running` by a conditional UPDATE (one worker wins), with a fresh attempt id;
* heartbeat: refreshes `heartbeat_at` while the job runs; False once the lease was taken away;
* complete: the results are written in the transaction that moves `running -> done`, and only
  if this attempt still holds the lease -- so a re-run job is counted once;
* reap: running jobs whose heartbeat is older than `lease_timeout` go back to the queue (or are
  failed for good with their reason after `max_attempts`).

The jobs table is the queue itself (league.server.jobs.queue): a job is queued by its row alone.

Each function takes the job handlers (kind -> JobHandler, league.server.jobs.handlers) whose
`begin`, `finish` and `give_up` run inside these transactions.
"""
from __future__ import annotations

import logging
from collections.abc import Mapping
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import ColumnElement, and_, case, func, or_, select, update
from sqlalchemy.orm import Session, aliased, sessionmaker

from league.server.db.models import (
    CANCELLED, CANNOT_SUCCEED, DONE, ERROR, EVALUATE, FAILED, QUEUED, RUNNING, UNKNOWN_KIND, VALIDATE, WORKER_LOST,
    PRIVATE_TRACKS, Evaluation, Job, private_test, utcnow,
)

log = logging.getLogger("league.server.jobs")
CANDIDATES = 8  # fairest queued jobs tried per claim (others' workers may take the first ones)


def claim_next(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, attempt_id: str) -> Job | None:
    """Claim the fairest queued job: normal priority before low (the re-evaluations of a settings
    change never delay a student's upload); within a priority owners take turns (a job's rank counts
    its owner's jobs of that priority running or queued before it; a final's private test is no
    student's: it waits for no job of theirs and delays none), so one student's backlog delays
    another's first job by one job at most; at equal rank validations go first, then evaluations,
    then races, then the oldest."""
    while candidates := fairest_queued(sessions):
        job = claim_first(sessions, handlers, job_ids=candidates, attempt_id=attempt_id)
        if job is not None:
            return job
        # every candidate went to another worker meanwhile (many claim at once): look again
    return None


def fairest_queued(sessions: sessionmaker[Session], limit: int = CANDIDATES) -> list[int]:
    """The ids of the `limit` fairest queued jobs, in claim order (claim_next's)."""
    with sessions() as session:
        return first_turns(session, limit) or ranked_queued(session, limit)


def first_turns(session: Session, limit: int) -> list[int]:
    """The fairest queued jobs when at least `limit` of them take their owner's first turn (rank 1: no
    job of their owner and priority running or queued before them) in the first priority waiting, as
    at a deadline: validations, then evaluations, then the rest, each read in the order of their ids
    from ix_jobs_queued_kind or ix_jobs_queued_other until `limit` passed, each checked by its owner's
    few jobs (ix_jobs_status_owner_turn). Else [] (ranked_queued answers)."""
    earlier = aliased(Job)

    def is_private_test(job: Any) -> ColumnElement[bool]:  # private_test() without a join: ids stay in order
        return select(Evaluation.id).where(Evaluation.id == job.evaluation_id,
                                           Evaluation.track == PRIVATE_TRACKS).exists()

    def before_it(same_owner: ColumnElement[bool]) -> ColumnElement[bool]:
        """A job of its owner and priority is running, or queued before it (two lookups by owner)."""
        ahead = select(earlier.id).where(same_owner, earlier.priority == Job.priority, ~is_private_test(earlier))
        return or_(ahead.where(earlier.status == RUNNING).exists(),
                   ahead.where(earlier.status == QUEUED, earlier.id < Job.id).exists())

    waits = or_(and_(Job.owner_id.is_not(None), before_it(earlier.owner_id == Job.owner_id)),
                and_(Job.owner_id.is_(None), before_it(earlier.owner_id.is_(None))))
    first_priority = select(func.min(Job.priority)).where(Job.status == QUEUED).scalar_subquery()
    ids: list[int] = []
    for kinds in (Job.kind == VALIDATE, Job.kind == EVALUATE, Job.kind.not_in((VALIDATE, EVALUATE))):
        ids += session.scalars(select(Job.id).where(
            Job.status == QUEUED, Job.priority == first_priority, kinds, or_(is_private_test(Job), ~waits)
        ).order_by(Job.id).limit(limit - len(ids)))
        if len(ids) == limit:
            return ids
    return []


def ranked_queued(session: Session, limit: int) -> list[int]:
    """The fairest queued jobs by ranking every queued and running one (the order's definition)."""
    active = Job.status.in_((QUEUED, RUNNING))
    # a final's private test takes no turn of its owner's: alone in its partition (ids from -2 down)
    turn_of = case((private_test(), -1 - Job.id), else_=func.coalesce(Job.owner_id, -1))
    rank = func.row_number().over(partition_by=(Job.priority, turn_of),
                                  order_by=(case((Job.status == RUNNING, 0), else_=1), Job.id))
    kind_order = case((Job.kind == VALIDATE, 0), (Job.kind == EVALUATE, 1), else_=2)
    ranked = select(Job.id, Job.status, Job.priority, rank.label("rank"), kind_order.label("kind_order")).outerjoin(
        Evaluation, Job.evaluation_id == Evaluation.id).where(active).subquery()
    return list(session.scalars(select(ranked.c.id).where(ranked.c.status == QUEUED).order_by(
        ranked.c.priority, ranked.c.rank, ranked.c.kind_order, ranked.c.id).limit(limit)))


def claim(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, job_id: int,
          attempt_id: str) -> Job | None:
    """Take a queued job for this attempt; None if it is not queued (done, failed, running elsewhere)."""
    return claim_first(sessions, handlers, job_ids=[job_id], attempt_id=attempt_id)


def claim_first(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, job_ids: list[int],
                attempt_id: str) -> Job | None:
    """Take the first of `job_ids` still queued for this attempt, in one transaction; None if none is.
    On PostgreSQL one statement finds and locks it, skipping the jobs other workers are taking (no
    transaction per candidate, no queueing behind their row locks)."""
    now = utcnow()
    with sessions.begin() as session:
        if session.get_bind().dialect.name == "postgresql":
            in_order = case({job_id: place for place, job_id in enumerate(job_ids)}, value=Job.id)
            job_ids = list(session.scalars(select(Job.id).where(Job.id.in_(job_ids), Job.status == QUEUED).order_by(
                in_order).limit(1).with_for_update(skip_locked=True)))
        job_id = next((job_id for job_id in job_ids if session.execute(
            update(Job).where(Job.id == job_id, Job.status == QUEUED)
            .values(status=RUNNING, worker_id=attempt_id, attempts=Job.attempts + 1, started_at=now, heartbeat_at=now)
        ).rowcount), None)
        if job_id is None:
            return None
        job = session.get(Job, job_id, populate_existing=True)
        if job.kind not in handlers:  # a row another version wrote: failed with the reason, not left waiting
            job.status, job.finished_at, job.worker_id, job.failure = FAILED, now, None, UNKNOWN_KIND
            job.error = (f"no worker of this version runs jobs of kind {job.kind!r} (knows "
                         f"{', '.join(sorted(handlers))}): queued by another version of microracer-league")
            log.error("job %s failed: %s", job_id, job.error)
            return None
        handlers[job.kind].begin(session, job)
        return job


def heartbeat(sessions: sessionmaker[Session], *, job_id: int, attempt_id: str) -> bool:
    """Refresh the lease; False if this attempt no longer holds it."""
    with sessions.begin() as session:
        return bool(session.execute(
            update(Job).where(Job.id == job_id, Job.status == RUNNING, Job.worker_id == attempt_id)
            .values(heartbeat_at=utcnow())
        ).rowcount)


def complete(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, job_id: int, attempt_id: str,
             outcome: Any) -> list[int]:
    """Write the outcome with `running -> done`, if this attempt holds the lease; the follow-up jobs."""
    with sessions.begin() as session:
        if not take_lease_for(session, job_id, attempt_id, DONE):
            log.warning("job %s: lease lost before completion; its results are discarded", job_id)
            return []
        job = session.get(Job, job_id, populate_existing=True)
        return handlers[job.kind].finish(session, job, outcome)


def take_lease_for(session: Session, job_id: int, attempt_id: str, status: str, **values: Any) -> bool:
    """Move this attempt's running job to `status`; row-locks it until the transaction ends."""
    return bool(session.execute(
        update(Job).where(Job.id == job_id, Job.status == RUNNING, Job.worker_id == attempt_id)
        .values(status=status, finished_at=utcnow() if status in (DONE, FAILED) else None, **values)
    ).rowcount)


def retry_or_fail(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, job_id: int, attempt_id: str,
                  reason: str) -> bool:
    """After an infrastructure failure: back to the queue (True), or failed for good after max_attempts."""
    with sessions.begin() as session:
        job = session.get(Job, job_id, populate_existing=True)
        if job.attempts >= job.max_attempts:
            if take_lease_for(session, job_id, attempt_id, FAILED, error=reason, failure=ERROR):
                handlers[job.kind].give_up(session, job, reason)
            return False
        return take_lease_for(session, job_id, attempt_id, QUEUED, error=reason, worker_id=None, enqueued_at=utcnow())


def fail(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, job_id: int, attempt_id: str,
         reason: str) -> None:
    """Fail this attempt's job for good, at once (it cannot succeed: retrying would only repeat it)."""
    with sessions.begin() as session:
        if take_lease_for(session, job_id, attempt_id, FAILED, error=reason, failure=CANNOT_SUCCEED):
            handlers[session.get(Job, job_id).kind].give_up(session, session.get(Job, job_id), reason)


def cancel(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, job_id: int, reason: str) -> bool:
    """Fail a queued or running job for good; a running one's worker loses its lease and stops.
    False if the job was already over."""
    with sessions.begin() as session:
        cancelled = session.execute(update(Job).where(Job.id == job_id, Job.status.in_((QUEUED, RUNNING))).values(
            status=FAILED, error=reason, failure=CANCELLED, worker_id=None, finished_at=utcnow())).rowcount
        if cancelled:
            job = session.get(Job, job_id, populate_existing=True)
            handlers[job.kind].give_up(session, job, reason)
        return bool(cancelled)


def hand_back(sessions: sessionmaker[Session], *, job_id: int, attempt_id: str, reason: str) -> bool:
    """Give a running job back to the queue at once (its worker shuts down); True if it was ours."""
    with sessions.begin() as session:
        return take_lease_for(session, job_id, attempt_id, QUEUED, worker_id=None, enqueued_at=utcnow(),
                              error=reason)


def release_running(session: Session, *, reason: str) -> int:
    """Every running job back to the queue, its attempt not counted: a restored database's jobs whose
    workers are gone (they would otherwise wait for the lease timeout). Returns how many."""
    return session.execute(update(Job).where(Job.status == RUNNING).values(
        status=QUEUED, worker_id=None, attempts=Job.attempts - 1, error=reason, enqueued_at=utcnow())).rowcount


def reap(sessions: sessionmaker[Session], handlers: Mapping[str, Any], *, lease_timeout_s: float,
         now: datetime | None = None) -> list[int]:
    """Re-queue running jobs whose worker stopped heart-beating; returns their ids.

    Safe to run in every worker at once: each change is a conditional UPDATE that only one of them can make.
    """
    now = now or utcnow()
    stale_before = now - timedelta(seconds=lease_timeout_s)
    with sessions() as session:
        stale = list(session.scalars(select(Job.id).where(Job.status == RUNNING, Job.heartbeat_at < stale_before)))
    return [job_id for job_id in stale if _release_stale(sessions, handlers, job_id, stale_before, now)]


def queue_depth(session: Session, now: datetime | None = None) -> tuple[int, float | None]:
    """How many jobs are queued, and how long the oldest has waited (seconds; None: none waits)."""
    count, oldest = session.execute(select(func.count(), func.min(Job.enqueued_at)).where(Job.status == QUEUED)).one()
    if oldest is None:
        return 0, None
    return count, max(0.0, ((now or utcnow()) - oldest).total_seconds())


def _release_stale(sessions: sessionmaker[Session], handlers: Mapping[str, Any], job_id: int,
                   stale_before: datetime, now: datetime) -> bool:
    still_stale = (Job.id == job_id, Job.status == RUNNING, Job.heartbeat_at < stale_before)
    with sessions.begin() as session:
        job = session.get(Job, job_id)
        reason = f"its worker ({job.worker_id}) stopped heart-beating"
        if job.attempts >= job.max_attempts:
            failed = session.execute(update(Job).where(*still_stale).values(
                status=FAILED, error=f"gave up after {job.attempts} attempts: {reason}", failure=WORKER_LOST,
                finished_at=now)).rowcount
            if failed:
                handlers[job.kind].give_up(session, job, f"gave up after {job.attempts} attempts: {reason}")
            return False
        requeued = session.execute(update(Job).where(*still_stale).values(
            status=QUEUED, worker_id=None, error=reason, enqueued_at=now)).rowcount
    if requeued:
        log.warning("job %s re-queued: %s", job_id, reason)
    return bool(requeued)
