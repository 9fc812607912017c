"""Workers: job threads that claim queued jobs from the database, the reaper, the worker's heartbeat.

`league worker` runs one in the foreground; `league serve` starts one as its child process
(league/server/cli.py), for the one-command embedded league. An idle job thread sleeps until a
wake-up (league.server.jobs.queue) or `queue_poll_s`, then looks at the jobs table again: a job
queued by any means runs within that poll while a worker is alive.
"""
from __future__ import annotations

import logging
import os
import signal
import threading
from collections.abc import Callable
from pathlib import Path

from sqlalchemy import Engine

import league

from league.server.core.config import Settings
from league.server.db import crud
from league.server.db.session import make_sessionmaker, schema_problem, stored_revision
from league.server.jobs import alive, registry
from league.server.jobs.handlers import HANDLERS
from league.server.jobs.placement import Placement
from league.server.jobs.queue import JobQueue
from league.server.jobs.runner import WorkerContext, prepare_job_thread, reap, release_active, run_next
from league.server.sandbox.process import ForkServer, sandbox_isolation
from league.server.storage import BlobStore
from league.track import set_track_cache_size

log = logging.getLogger("league.server.worker")
SIGNAL_CHECK_S = 0.5  # the main thread wakes this often to act on a signal


class Periodic:
    """A daemon thread doing `work` every `interval_s` until stopped; a failing pass is logged, not fatal
    (the reaper is what recovers from outages)."""

    def __init__(self, name: str, interval_s: float, work: Callable[[], None]):
        self.name, self.interval_s, self.work = name, interval_s, work
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)

    def start(self) -> None:
        """Start the thread (again after a stop: an app's lifespan may run more than once)."""
        if self._thread.ident is not None:
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._loop, name=self.name, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def _loop(self) -> None:
        while True:
            try:
                self.work()
            except Exception:  # noqa: BLE001
                log.exception("%s: pass failed", self._thread.name)
            if self._stop.wait(self.interval_s):
                return


class Worker:
    def __init__(self, context: WorkerContext, *, threads: int,
                 prepare_thread: Callable[[Settings], None] = prepare_job_thread):
        settings = context.settings
        if settings.cpu_placement and context.placement is None:
            context.placement = Placement(threads, Path(settings.cpu_slots_dir) if settings.cpu_slots_dir else None)
        self.context, self.prepare_thread = context, prepare_thread  # (tests run jobs without sandboxes)
        self.threads = [threading.Thread(target=self._job_thread, name=f"league-job-{n}", daemon=True)
                        for n in range(threads)]
        self.draining = threading.Event()  # claim no new job (SIGINT): the running ones finish
        self.signals: list[int] = []  # received, acted on by the main thread
        self.worker_id: int | None = None
        self.outdated: str | None = None  # why this process stopped: the database's schema is not its own
        self.reaper = Periodic("league-reaper", settings.reaper_interval_s, self._reap)
        self.beat = Periodic("league-worker-beat", settings.worker_heartbeat_s, self._beat)
        self._stop_listening = threading.Event()

    def run_forever(self) -> None:
        """Run in the foreground until SIGINT (graceful: running jobs finish; a second one stops at once)
        or SIGTERM (running jobs are handed back to the queue at once)."""
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda number, frame: self.signals.append(number))
        self.start()
        try:
            self._wait()
        finally:
            self.stop()

    def start(self) -> None:
        """Register, then start the heartbeat, the reaper, the listener (NOTIFY, or the SQLite files) and the job
        threads."""
        self.worker_id = registry.register(self.context.sessions)
        set_track_cache_size(self.context.settings.track_cache_size)  # the job threads share the tracks
        self.beat.start()
        self.reaper.start()
        queue = self.context.queue
        if queue.listens:
            threading.Thread(target=queue.listen, args=(self._stop_listening,), name="league-listener",
                             daemon=True).start()
        for thread in self.threads:
            thread.start()
        woken = ", woken by NOTIFY" if queue.notifies else ", woken by the database's commits" if queue.listens else ""
        log.info("worker started: %d job threads claiming from the database (looking every %g s%s)",
                 len(self.threads), self.context.settings.resolved_queue_poll_s, woken)

    def stop(self) -> None:
        """Claim no more, hand the running jobs back, stop the other threads, unregister."""
        self.draining.set()
        self.context.queue.wakeup.wake()
        self._hand_back()
        self._stop_listening.set()
        self.reaper.stop()
        self.beat.stop()
        try:
            registry.unregister(self.context.sessions, self.worker_id)
        except Exception:  # noqa: BLE001 - the database is gone: its row ages out of /api/health
            log.warning("could not remove this worker from the workers table", exc_info=True)
        self._release_cpus()

    def _wait(self) -> None:
        """Until the job threads end after a SIGINT, or at once on SIGTERM or a second SIGINT."""
        while alive := [thread for thread in self.threads if thread.is_alive()]:
            if signal.SIGTERM in self.signals or self.signals.count(signal.SIGINT) > 1:
                return
            if self.signals and not self.draining.is_set():
                log.info("stopping once the running jobs finish (Ctrl-C again: hand them back now)")
                self.draining.set()
                self.context.queue.wakeup.wake()
            alive[0].join(SIGNAL_CHECK_S)

    def _job_thread(self) -> None:
        context = self.context
        self.prepare_thread(context.settings)
        wakeup, poll_s = context.queue.wakeup, context.settings.resolved_queue_poll_s
        while not self.draining.is_set():
            seen = wakeup.generation
            try:
                ran = run_next(context)
            except Exception:  # noqa: BLE001 - an outage: log it, look again after the poll
                log.exception("job thread: claiming or running a job failed")
                ran = False
            if not ran:
                wakeup.wait(seen, poll_s)

    def _reap(self) -> None:
        requeued = reap(self.context)
        if requeued:
            log.info("reaper re-queued jobs %s", requeued)
        sweep_store(self.context.sessions, self.context.store)
        alive.beat(alive.alive_file(self.context.settings.data_dir))  # `league worker --check`

    def _beat(self) -> None:
        """Beat, and stop if the schema changed under us (an upgrade whose `league migrate` did not see
        this worker): running on would fail each job on missing columns; the message says what to do."""
        self.worker_id = registry.beat(self.context.sessions, self.worker_id,
                                       self.context.settings.worker_silent_after_s)
        self.outdated = schema_changed(self.context.sessions)
        if self.outdated:
            log.error("worker stopping: %s", self.outdated)
            self.signals.append(signal.SIGTERM)  # the main thread hands the running jobs back and stops

    def _release_cpus(self) -> None:
        if self.context.placement is not None:
            self.context.placement.close()

    def _hand_back(self) -> None:
        released = release_active(self.context)
        if released:
            log.info("handed jobs %s back to the queue", released)


def schema_changed(sessions) -> str | None:
    """What to do if the database's schema is no longer this installation's (None while it is)."""
    with sessions() as session:
        problem = schema_problem(stored_revision(session.connection()))
    return None if problem is None else (f"the database's schema changed under this running process "
                                         f"(microracer-league {league.__version__}): {problem}, then restart it")


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
    return WorkerContext(settings, make_sessionmaker(engine), queue or JobQueue(engine), store, HANDLERS)


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
