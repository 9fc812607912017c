"""Workers: a Huey consumer that runs league jobs, and the reaper that keeps jobs from getting stuck.

`league worker` runs one in the foreground (Huey handles SIGINT/SIGTERM); `league serve` starts
one as its child process (league/server/cli.py), for the one-command embedded league.
"""
from __future__ import annotations

import logging
import os
import threading
from pathlib import Path

from huey.consumer import Consumer
from sqlalchemy import Engine

from league.server.config import Settings
from league.server.db import crud
from league.server.db.session import make_sessionmaker
from league.server.jobs.alive import alive_file, beat
from league.server.jobs.handlers import HANDLERS
from league.server.jobs.placement import Placement
from league.server.jobs.queue import JobQueue, build_queue
from league.server.jobs.runner import WorkerContext, prepare_job_thread, reap, release_active, run_job
from league.server.sandbox.process import ForkServer, sandbox_isolation
from league.server.storage import BlobStore

log = logging.getLogger("league.server.worker")
MAX_POLL_DELAY_S = 1.0  # an idle SQLite-queue worker looks for work at least this often (Redis blocks instead)


class Reaper:
    def __init__(self, context: WorkerContext):
        self.context = context
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="league-reaper", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def _loop(self) -> None:
        resend_after_s = 0.0  # the first pass re-sends every queued job: a restore or a lost queue left no message
        while True:
            try:
                sent = reap(self.context, resend_after_s)
                resend_after_s = self.context.settings.requeue_queued_after_s
                if sent:
                    log.info("reaper re-sent jobs %s", sent)
                sweep_store(self.context.sessions, self.context.store)
                beat(alive_file(self.context.settings.data_dir))  # `league worker --check`
            except Exception:  # an outage must not end the reaper: it is what recovers from outages
                log.exception("reaper pass failed")
            if self._stop.wait(self.context.settings.reaper_interval_s):
                return


class Worker:
    def __init__(self, context: WorkerContext, *, threads: int):
        context.queue.runner = lambda job_id: run_job(context, job_id)
        settings = context.settings
        context.queue.huey.on_startup("league-job-thread")(lambda: prepare_job_thread(settings))  # in each
        if settings.cpu_placement and context.placement is None:
            context.placement = Placement(threads, Path(settings.cpu_slots_dir) if settings.cpu_slots_dir else None)
        self.context = context
        self.consumer = Consumer(context.queue.huey, workers=threads, periodic=False,
                                       max_delay=MAX_POLL_DELAY_S, check_worker_health=True)
        self.reaper = Reaper(context)

    def run_forever(self) -> None:
        """Run in the foreground until SIGINT (graceful: running jobs finish) or SIGTERM (they are handed back)."""
        self.reaper.start()
        try:
            self.consumer.run()
        finally:
            self._hand_back()
            self.reaper.stop()
            self._release_cpus()

    def _release_cpus(self) -> None:
        if self.context.placement is not None:
            self.context.placement.close()

    def _hand_back(self) -> None:
        released = release_active(self.context)
        if released:
            log.info("handed jobs %s back to the queue", released)


def sweep_store(sessions, store: BlobStore) -> None:
    """Remove the local copies of files the database no longer keeps (rejected uploads)."""
    with sessions() as session:
        kept = crud.kept_blobs(session)
    removed = store.sweep(kept)
    if removed:
        log.info("removed %d model files no longer kept", len(removed))


def worker_context(settings: Settings, engine: Engine, queue: JobQueue | None = None) -> WorkerContext:
    """What a worker's jobs work with, on the league's database (its schema checked: workers never migrate)."""
    store = BlobStore(settings.data_dir)
    store.ensure()
    sandbox_isolation(settings.sandbox_uid_base)  # logged at start-up: what this machine's sandboxes get
    ForkServer.release_this_thread()  # (the probe's: this thread runs no job)
    return WorkerContext(settings, make_sessionmaker(engine), queue or build_queue(settings), store, HANDLERS)


def pin_to_cpus(spec: str) -> set[int]:
    """Run this process, its threads and the sandboxes they start on the CPUs of a taskset-style
    list ("1", "0-3,6"). A race's sandboxes run in parallel on every CPU they may use, so an
    unpinned worker takes more than one CPU; pinning gives each worker a fixed share (leave CPUs
    to the API and the database, or run one worker per CPU)."""
    cpus: set[int] = set()
    for part in spec.replace(" ", "").split(","):
        first, _, last = part.partition("-")
        if not first.isdigit() or (last and not last.isdigit()) or int(last or first) < int(first):
            raise ValueError(f"{part!r} is not a CPU number or range such as 2 or 0-3")
        cpus.update(range(int(first), int(last or first) + 1))
    available = os.sched_getaffinity(0)
    if not cpus <= available:
        raise ValueError(f"CPU {min(cpus - available)} is not available here "
                         f"(this process may run on {','.join(map(str, sorted(available)))})")
    for thread in os.listdir("/proc/self/task"):  # the threads imports started too (OpenBLAS)
        os.sched_setaffinity(int(thread), cpus)
    return cpus
