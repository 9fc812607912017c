"""The jobs table is the queue (both backends): a job queued by its row alone, with no wake-up at all
(a restore, a lost notification, another process's insert), runs within a poll while a worker is
alive; another process's enqueue wakes the workers at once (a NOTIFY, or on SQLite the commit's change
to the database's files); two workers never run one job. In-process workers with a recording job
kind (no sandboxes)."""
from __future__ import annotations

import threading
from collections import Counter

import pytest

from league.constants import TRACK_CACHE_SIZE
from league.server.core.config import Settings
from league.server.db import crud
from league.server.db.models import DONE, Job, WorkerProcess
from league.server.db.session import make_engine, make_sessionmaker, migrate
from league.server.jobs.queue import JobQueue
from league.server.jobs.runner import WorkerContext
from league.server.jobs.worker import Worker
from league.server.storage import BlobStore
from league.track import set_track_cache_size, track_cache_info

from ..api_calls import wait_for


class Counting:
    """A job kind that counts the runs of each job, from any thread."""

    parallel_sandboxes = False

    def __init__(self):
        self.runs: Counter[int] = Counter()
        self._lock = threading.Lock()

    def begin(self, session, job):
        pass

    def run(self, run):
        with self._lock:
            self.runs[run.job.id] += 1
        return {}

    def finish(self, session, job, outcome):
        return []

    def give_up(self, session, job, reason):
        pass


@pytest.fixture
def league(backend, tmp_path):
    """(start_worker, sessions, handler) of a fresh database; the workers started are stopped."""
    _, database_url = backend
    settings = Settings(_env_file=None, data_dir=tmp_path / "data", database_url=database_url, bootstrap=False,
                        cpu_placement=False, reaper_interval_s=0.5, worker_heartbeat_s=0.5)
    engine = make_engine(database_url)
    migrate(engine)
    workers: list[Worker] = []

    def start_worker(threads: int = 2, watch: bool = True, **changed) -> Worker:
        queue = JobQueue(engine)
        if not watch:
            queue.watched = ()  # no listener on SQLite: only the poll finds a job
        context = WorkerContext(settings.model_copy(update=changed), make_sessionmaker(engine), queue,
                                BlobStore(settings.data_dir), handlers={"count": handler})
        worker = Worker(context, threads=threads, prepare_thread=lambda settings: None)
        worker.start()
        workers.append(worker)
        return worker

    handler = Counting()
    yield start_worker, make_sessionmaker(engine), handler
    for worker in workers:
        worker.stop()
    engine.dispose()


def insert_jobs(sessions, count: int) -> list[int]:
    """Queued jobs written straight into the table, as a restore or another process leaves them: no wake-up."""
    with sessions.begin() as session:
        return [crud.create_job(session, kind="count", owner_id=None).id for _ in range(count)]


def statuses(sessions, ids: list[int]) -> set[str]:
    with sessions() as session:
        return {session.get(Job, job_id).status for job_id in ids}


def test_a_job_inserted_without_a_wake_up_runs_within_a_poll(league):
    start_worker, sessions, handler = league
    worker = start_worker(watch=False)
    generation = worker.context.queue.wakeup.generation
    ids = insert_jobs(sessions, 3)
    # the default polls are 0.5 s (SQLite) and 2 s (PostgreSQL): 10 s is a bound for a loaded machine
    wait_for(lambda: statuses(sessions, ids), lambda found: found == {DONE}, timeout=10)
    assert handler.runs == Counter({job_id: 1 for job_id in ids})
    if not worker.context.queue.listens:
        assert worker.context.queue.wakeup.generation == generation  # nothing woke it: its poll found them


def test_on_sqlite_another_connections_commit_wakes_the_workers(backend, league):
    """Their listener watches the database's files: with a poll of 10 minutes, the job runs all the same."""
    if backend[0] != "sqlite":
        pytest.skip("PostgreSQL's workers are woken by NOTIFY (the next test)")
    start_worker, sessions, handler = league
    worker = start_worker(queue_poll_s=600)
    wait_for(lambda: worker.context.queue.wakeup.generation, lambda generation: generation >= 1)  # watching
    api_engine = make_engine(sessions.kw["bind"].url.render_as_string(hide_password=False))  # another process's
    try:
        [job_id] = insert_jobs(make_sessionmaker(api_engine), 1)
        wait_for(lambda: statuses(sessions, [job_id]), lambda found: found == {DONE}, timeout=60)
    finally:
        api_engine.dispose()
    assert handler.runs == Counter({job_id: 1})


def test_on_postgresql_an_enqueue_in_another_process_wakes_the_workers(backend, league):
    if backend[0] != "postgres":
        pytest.skip("SQLite has no notifications: its workers poll")
    start_worker, sessions, _ = league
    wakeup = start_worker().context.queue.wakeup
    wait_for(lambda: wakeup.generation, lambda generation: generation >= 1)  # listening (it woke once then)
    generation = wakeup.generation
    api_engine = make_engine(sessions.kw["bind"].url.render_as_string(hide_password=False))  # another process's
    try:
        JobQueue(api_engine).enqueue(1)
        wait_for(lambda: wakeup.generation, lambda now: now > generation, timeout=10)
    finally:
        api_engine.dispose()


def test_two_workers_never_run_one_job(league):
    start_worker, sessions, handler = league
    ids = insert_jobs(sessions, 60)
    start_worker(threads=2)
    start_worker(threads=2)
    wait_for(lambda: statuses(sessions, ids), lambda found: found == {DONE}, timeout=120)
    assert handler.runs == Counter({job_id: 1 for job_id in ids})


def test_a_worker_is_listed_while_it_runs(league):
    start_worker, sessions, _ = league
    worker = start_worker(threads=1)
    with sessions() as session:
        row = session.get(WorkerProcess, worker.worker_id)
        assert row is not None and row.pid > 0
    worker.stop()
    with sessions() as session:
        assert session.get(WorkerProcess, worker.worker_id) is None


def test_a_worker_keeps_as_many_episode_starts_as_its_setting_says(backend, tmp_path):
    """Its job threads share one track cache (issue 33): sized by LEAGUE_TRACK_CACHE_SIZE."""
    _, database_url = backend
    settings = Settings(_env_file=None, data_dir=tmp_path / "data", database_url=database_url, bootstrap=False,
                        cpu_placement=False, track_cache_size=7)
    engine = make_engine(database_url)
    migrate(engine)
    worker = Worker(WorkerContext(settings, make_sessionmaker(engine), JobQueue(engine), BlobStore(settings.data_dir),
                                  handlers={}), threads=1, prepare_thread=lambda settings: None)
    try:
        worker.start()
        assert track_cache_info().maxsize == 7
    finally:
        worker.stop()
        set_track_cache_size(TRACK_CACHE_SIZE)
        engine.dispose()
