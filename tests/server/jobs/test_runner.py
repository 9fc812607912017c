"""Job leases on a real database (both backends; the jobs table is the queue): claimed once, results
written once, stale jobs re-queued by the reaper, failed for good after their attempts."""
from __future__ import annotations

import os
import threading
from datetime import timedelta

import pytest
from sqlalchemy import select

from league.server.core.config import Settings
from league.server.db import crud
from league.server.db.models import (
    DONE, FAILED, LOW, PRIVATE_TRACKS, PUBLIC_TRACKS, QUEUED, RUNNING, Evaluation, Job, Submission, utcnow,
)
from league.server.db.session import make_engine, make_sessionmaker, migrate
from league.server.jobs.leases import (
    cancel, claim, claim_next, complete, fairest_queued, first_turns, heartbeat, ranked_queued,
)
from league.server.jobs.placement import Placement
from league.server.jobs.queue import JobQueue
from league.server.jobs.runner import JobCannotSucceed, JobRun, WorkerContext, reap, release_active, run_next
from league.server.storage import BlobStore


class Recorder:
    """A job kind for these tests: records what the lease machinery asks of it."""

    def __init__(self):
        self.begun, self.finished, self.given_up = [], [], []
        self.fail_with: Exception | None = None

    def begin(self, session, job):
        self.begun.append(job.id)

    def run(self, run):
        if self.fail_with:
            raise self.fail_with
        return {"job": run.job.id}

    def finish(self, session, job, outcome):
        self.finished.append(outcome)
        return []

    def give_up(self, session, job, reason):
        self.given_up.append((job.id, reason))


@pytest.fixture
def context(backend, tmp_path):
    _, database_url = backend
    settings = Settings(data_dir=tmp_path / "data", database_url=database_url, lease_timeout_s=60, bootstrap=False)
    engine = make_engine(database_url)
    migrate(engine)
    yield WorkerContext(settings, make_sessionmaker(engine), JobQueue(engine), BlobStore(settings.data_dir),
                        handlers={"test": Recorder()})
    engine.dispose()


@pytest.fixture
def recorder(context):
    return context.handlers["test"]


def new_job(context, max_attempts: int = 3) -> int:
    with context.sessions.begin() as session:
        return crud.create_job(session, kind="test", owner_id=None, max_attempts=max_attempts).id


def job(context, job_id: int) -> Job:
    with context.sessions() as session:
        return session.get(Job, job_id)


def age(context, job_id: int, **columns_ago) -> None:
    """Pretend time passed: move the job's timestamps into the past."""
    with context.sessions.begin() as session:
        row = session.get(Job, job_id)
        for column, seconds in columns_ago.items():
            setattr(row, column, utcnow() - timedelta(seconds=seconds))


def test_a_job_is_claimed_by_one_attempt_only(context, recorder):
    job_id = new_job(context)
    winners = []

    def attempt(name):
        if claim(context.sessions, context.handlers, job_id=job_id, attempt_id=name) is not None:
            winners.append(name)

    threads = [threading.Thread(target=attempt, args=(f"w{i}",)) for i in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(winners) == 1 and recorder.begun == [job_id]
    row = job(context, job_id)
    assert (row.status, row.worker_id, row.attempts) == (RUNNING, winners[0], 1)


def test_run_next_writes_the_outcome_once(context, recorder):
    job_id = new_job(context)
    assert run_next(context)
    assert not run_next(context)  # nothing else queued
    assert recorder.finished == [{"job": job_id}]
    assert (job(context, job_id).status, job(context, job_id).attempts) == (DONE, 1)


def test_results_of_an_attempt_that_lost_its_lease_are_discarded(context, recorder):
    job_id = new_job(context)
    claim(context.sessions, context.handlers, job_id=job_id, attempt_id="slow")
    age(context, job_id, heartbeat_at=120)
    assert reap(context) == [job_id]  # re-queued for another worker
    assert not heartbeat(context.sessions, job_id=job_id, attempt_id="slow")

    assert complete(context.sessions, context.handlers, job_id=job_id, attempt_id="slow", outcome={"late": True}) == []

    assert recorder.finished == []
    row = job(context, job_id)
    assert (row.status, row.worker_id) == (QUEUED, None)
    assert "stopped heart-beating" in row.error


def test_reaper_leaves_fresh_leases_alone(context, recorder):
    job_id = new_job(context)
    claim(context.sessions, context.handlers, job_id=job_id, attempt_id="alive")
    assert heartbeat(context.sessions, job_id=job_id, attempt_id="alive")
    assert reap(context) == []
    assert job(context, job_id).status == RUNNING


def test_a_job_whose_workers_keep_dying_fails_for_good_with_the_reason(context, recorder):
    job_id = new_job(context, max_attempts=2)
    for attempt in ("first", "second"):
        assert claim(context.sessions, context.handlers, job_id=job_id, attempt_id=attempt) is not None
        age(context, job_id, heartbeat_at=120)
        reap(context)
    row = job(context, job_id)
    assert (row.status, row.attempts) == (FAILED, 2)
    assert row.error == "gave up after 2 attempts: its worker (second) stopped heart-beating"
    assert recorder.given_up == [(job_id, row.error)]


def test_a_failing_handler_is_retried_then_failed(context, recorder):
    recorder.fail_with = RuntimeError("disk full")
    job_id = new_job(context, max_attempts=2)
    run_next(context)
    assert (job(context, job_id).status, job(context, job_id).error) == (QUEUED, "RuntimeError: disk full")
    run_next(context)
    assert job(context, job_id).status == FAILED
    assert recorder.given_up == [(job_id, "RuntimeError: disk full")]


def test_a_long_queued_job_is_left_to_the_claims(context, recorder):
    """Queued for an hour (its wake-up lost): nothing to re-send, the next claim takes it."""
    job_id = new_job(context)
    age(context, job_id, enqueued_at=3600)
    assert reap(context) == []
    assert run_next(context) and job(context, job_id).status == DONE


def test_a_job_of_a_kind_no_handler_knows_fails_with_the_reason(context, recorder):
    """A row an older release queued under a kind since renamed fails at once, saying so, and the
    claim goes on to the next job instead of leaving it waiting."""
    with context.sessions.begin() as session:
        renamed = crud.create_job(session, kind="run_job", owner_id=None).id
    known = new_job(context)
    assert run_next(context)
    row = job(context, renamed)
    assert (row.status, row.worker_id) == (FAILED, None)
    assert row.error == ("no worker of this version runs jobs of kind 'run_job' (knows test): queued by another "
                         "version of microracer-league")
    assert job(context, known).status == DONE


def test_a_worker_shutting_down_hands_its_jobs_back(context, recorder):
    job_id = new_job(context)
    claimed = claim(context.sessions, context.handlers, job_id=job_id, attempt_id="leaving")
    run = JobRun(context, claimed, "leaving")
    context.active[job_id] = run
    generation = context.queue.wakeup.generation

    assert release_active(context) == [job_id]

    assert run.lease_lost.is_set()
    row = job(context, job_id)
    assert (row.status, row.worker_id, row.error) == (QUEUED, None, "its worker shut down")
    assert context.queue.wakeup.generation == generation + 1  # this worker's idle threads look again
    assert complete(context.sessions, context.handlers, job_id=job_id, attempt_id="leaving", outcome={}) == []


class AffinityRecorder(Recorder):
    """A job kind that records the CPUs its thread may use while it runs."""

    def __init__(self, parallel_sandboxes: bool):
        super().__init__()
        self.parallel_sandboxes = parallel_sandboxes

    def run(self, run):
        return {"cpus": sorted(os.sched_getaffinity(0))}


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs")
def test_a_job_thread_is_placed_by_the_kind_of_its_job(context, tmp_path):
    cpus = sorted(os.sched_getaffinity(0))
    context.placement = Placement(1, tmp_path / "slots")
    for kind, parallel in (("test-one-sandbox", False), ("test-race", True)):
        context.handlers[kind] = AffinityRecorder(parallel)
    with context.sessions.begin() as session:
        ids = [crud.create_job(session, kind=kind, owner_id=None).id for kind in ("test-one-sandbox", "test-race")]
    worker = threading.Thread(target=lambda: [run_next(context) for job_id in ids])  # a job thread
    worker.start()
    worker.join()
    with context.sessions() as session:
        assert [session.get(Job, job_id).status for job_id in ids] == [DONE, DONE]
    assert context.handlers["test-one-sandbox"].finished == [{"cpus": cpus[:1]}]  # its sandbox beside it
    assert context.handlers["test-race"].finished == [{"cpus": cpus}]  # alone on the machine: every CPU
    context.placement.close()


# --------------------------------------------------------------------------- a fair queue


def owners(context, count: int) -> list[int]:
    with context.sessions.begin() as session:
        return [crud.create_user(session, name=f"owner-{os.getpid()}-{i}-{id(context)}", role="student",
                                 course=None)[0].id for i in range(count)]


def queued_jobs(context, owner: int, kinds: list[str]) -> list[int]:
    with context.sessions.begin() as session:
        return [crud.create_job(session, kind=kind, owner_id=owner).id for kind in kinds]


def test_one_students_backlog_delays_anothers_first_job_by_one_job_at_most(context):
    alice, bob = owners(context, 2)
    backlog = queued_jobs(context, alice, ["validate"] * 10)
    first = queued_jobs(context, bob, ["validate"])
    assert fairest_queued(context.sessions, limit=3) == [backlog[0], first[0], backlog[1]]
    claim(context.sessions, {"validate": Recorder()}, job_id=backlog[0], attempt_id="busy")  # alice's job runs
    assert fairest_queued(context.sessions, limit=2) == [first[0], backlog[1]]  # bob's first, while hers runs


def test_validations_go_before_evaluations_and_races(context):
    alice, bob, carol = owners(context, 3)
    race, evaluation, validation = (queued_jobs(context, owner, [kind])[0]
                                    for owner, kind in ((alice, "race"), (bob, "evaluate"), (carol, "validate")))
    assert fairest_queued(context.sessions, limit=3) == [validation, evaluation, race]


def test_a_students_jobs_are_claimed_before_any_low_priority_re_evaluation(context):
    """The backlog of a settings change (everyone's re-evaluations, older than the upload) waits, and
    one's own re-evaluations, queued or running, do not hold one's upload back behind others'."""
    alice, bob = owners(context, 2)
    with context.sessions.begin() as session:
        backlog = [crud.create_job(session, kind="evaluate", owner_id=owner, priority=LOW).id
                   for owner in (alice, bob) for _ in range(3)]
    handlers = {kind: Recorder() for kind in ("validate", "evaluate", "race")}
    claim(context.sessions, handlers, job_id=backlog[0], attempt_id="busy")  # one of alice's runs
    uploads = queued_jobs(context, alice, ["validate", "evaluate"]) + queued_jobs(context, bob, ["race"])
    assert fairest_queued(context.sessions, limit=5) == [uploads[0], uploads[2], uploads[1], backlog[3], backlog[1]]
    claimed = [claim_next(context.sessions, handlers, attempt_id=f"w{i}").id for i in range(4)]
    assert claimed == [uploads[0], uploads[2], uploads[1], backlog[3]]


def test_the_first_turns_read_from_the_index_are_the_ranking_of_every_job(context):
    """The claim's short way (first_turns: the first jobs that take their owner's first turn) gives the
    full ranking's candidates (ranked_queued) whenever it answers, on random queues: owners with
    backlogs and running jobs, both priorities, every kind, private tests, jobs of no owner."""
    import random

    rng = random.Random(7)
    students = owners(context, 30)
    with context.sessions.begin() as session:
        submission = Submission(owner_id=students[0], name="m", filename="m.onnx", kind="onnx", sha256="0" * 64, size=1)
        session.add(submission)
        session.flush()
        for _ in range(160):
            owner = rng.choice([*students, None])
            track = rng.choice([PUBLIC_TRACKS, PRIVATE_TRACKS]) if owner is not None and rng.random() < 0.3 else None
            evaluation_id = None
            if track is not None:
                evaluation = Evaluation(submission_id=submission.id, track=track, settings={}, result_key="k")
                session.add(evaluation)
                session.flush()
                evaluation_id = evaluation.id
            job = crud.create_job(session, kind="evaluate" if track else rng.choice(["validate", "evaluate", "race"]),
                                  owner_id=owner, evaluation_id=evaluation_id, priority=rng.choice([0, 0, 0, LOW]))
            job.status = rng.choice([QUEUED, QUEUED, QUEUED, RUNNING, DONE])
    answered = 0
    for step in range(40):
        with context.sessions() as session:
            for limit in (1, 3, 8):
                fast = first_turns(session, limit)
                assert fast in ([], ranked_queued(session, limit)), (step, limit)
                answered += bool(fast)
        with context.sessions.begin() as session:  # the queue moves on: one claimed, one finished
            head = ranked_queued(session, 1)
            if head:
                session.get(Job, head[0]).status = RUNNING
            running = session.scalars(select(Job).where(Job.status == RUNNING).limit(1)).first()
            if running is not None and step % 2:
                running.status = DONE
    assert answered >= 40  # the short way answered a third of the claims at least: the check above is not idle


def test_a_job_that_cannot_succeed_fails_once_without_retrying(context, recorder):
    recorder.fail_with = JobCannotSucceed("the file of submission 7 is no longer kept")
    job_id = new_job(context, max_attempts=3)
    run_next(context)
    row = job(context, job_id)
    assert (row.status, row.attempts, row.error) == (FAILED, 1, "the file of submission 7 is no longer kept")
    assert recorder.given_up == [(job_id, "the file of submission 7 is no longer kept")]


def test_a_running_job_cancelled_loses_its_lease_and_its_results(context, recorder):
    job_id = new_job(context)
    claim(context.sessions, context.handlers, job_id=job_id, attempt_id="running")
    assert cancel(context.sessions, context.handlers, job_id=job_id, reason="cancelled by prof")
    assert not heartbeat(context.sessions, job_id=job_id, attempt_id="running")  # its worker stops
    assert complete(context.sessions, context.handlers, job_id=job_id, attempt_id="running", outcome={}) == []
    assert (job(context, job_id).status, recorder.given_up) == (FAILED, [(job_id, "cancelled by prof")])
    assert not cancel(context.sessions, context.handlers, job_id=job_id, reason="again")
