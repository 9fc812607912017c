"""Benchmark of the queue's worst case: a job whose wake-up was lost, from its row to a worker running it.

    python benchmarks/bench_queue.py [--backend sqlite|postgres|both] [--jobs 20]

`league serve --no-worker` and one `league worker` on a fresh league (1-episode evaluations); once
the baseline is evaluated, --jobs evaluation jobs of it are written one at a time straight into the
jobs table, as a restore, an upgrade or another process leaves them, with no wake-up at all (the
"lost message" case: before the database was the queue, such a job waited for the re-send after
600 s). Each is committed at a random moment of the worker's poll period; timed from the commit
until its row says `running` (read every 10 ms). On SQLite that commit is itself the workers'
wake-up (their listeners watch the database's files); on PostgreSQL a row alone waits for a poll,
and the same again with the wake-up that every enqueue sends (NOTIFY), for comparison. Printed:
median, p90 and maximum (target <= 5 s); exit status 1 if the maximum is over the target.
"""
from __future__ import annotations

import argparse
import random
import statistics
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from _league import Deadline, League, backend, machine, run_script

TARGET_S = 5.0
READ_EVERY_S = 0.01
CASES = (("sqlite", 0.5, False), ("postgres", 2.0, False), ("postgres", 2.0, True))  # with the default polls


@dataclass
class Case:
    """One backend's figures: seconds from each job's commit to its row saying `running`."""

    backend: str
    poll_s: float  # the worker's poll period on this backend
    wake: bool  # each job sent its wake-up (NOTIFY)
    latencies: list[float]

    @property
    def worst(self) -> float:
        return max(self.latencies)


def idle(sessions) -> bool:
    from sqlalchemy import func, select

    from league.server.db.models import QUEUED, RUNNING, Job

    with sessions() as session:
        return not session.scalar(select(func.count()).where(Job.status.in_((QUEUED, RUNNING))))


def queue_one(sessions) -> int:
    """A re-evaluation of the baseline, committed as a queued row only."""
    from sqlalchemy import select

    from league.server.course.results import queue_evaluation
    from league.server.db.models import Submission

    with sessions.begin() as session:
        baseline = session.scalars(select(Submission).order_by(Submission.id)).first()
        return queue_evaluation(session, submission=baseline, max_attempts=1).id


def seconds_to_running(sessions, job_id: int, committed: float) -> float:
    from league.server.db.models import QUEUED, Job

    deadline = Deadline(60, f"job {job_id} to start")
    while True:
        with sessions() as session:
            if session.get(Job, job_id).status != QUEUED:
                return time.perf_counter() - committed
        deadline.check()
        time.sleep(READ_EVERY_S)


def measure(kind: str, jobs: int, poll_s: float, wake: bool, rng: random.Random) -> list[float]:
    from league.server.db.session import make_engine, make_sessionmaker
    from league.server.jobs.queue import JobQueue

    with tempfile.TemporaryDirectory(prefix="league-queue-") as tmp, backend(kind, Path(tmp)) as urls:
        settings = {**urls, "LEAGUE_EVAL_EPISODES": "1"}
        with League(Path(tmp), embedded=False, settings=settings) as league:
            league.start_worker(wait=True)
            engine = make_engine(urls["LEAGUE_DATABASE_URL"])
            sessions, queue = make_sessionmaker(engine), JobQueue(engine)
            try:
                deadline = Deadline(300, "the baseline's evaluation")
                while not idle(sessions):
                    deadline.check()
                    time.sleep(0.1)
                latencies = []
                for _ in range(jobs):
                    time.sleep(rng.uniform(0, poll_s))  # anywhere in the worker's poll period
                    job_id = queue_one(sessions)
                    committed = time.perf_counter()
                    if wake:
                        queue.enqueue(job_id)
                    latencies.append(seconds_to_running(sessions, job_id, committed))
                    deadline = Deadline(120, f"job {job_id} to finish")
                    while not idle(sessions):
                        deadline.check()
                        time.sleep(0.05)
                return latencies
            finally:
                engine.dispose()


def summary(latencies: list[float]) -> str:
    ordered = sorted(latencies)
    p90 = ordered[min(len(ordered) - 1, int(0.9 * len(ordered)))]
    return (f"median {statistics.median(ordered):.2f} s, p90 {p90:.2f} s, max {ordered[-1]:.2f} s "
            f"(target <= {TARGET_S:g} s: {'ok' if ordered[-1] <= TARGET_S else 'OVER TARGET'})")


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backend", choices=["sqlite", "postgres", "both"], default="both",
                        help="sqlite, the local PostgreSQL (LEAGUE_BENCH_PG), or both (default)")
    parser.add_argument("--jobs", type=int, default=20, help="jobs timed per case")
    parser.add_argument("--seed", type=int, default=0)
    return parser.parse_args(argv)


def cases(args: argparse.Namespace) -> list[tuple[str, float, bool]]:
    return [case for case in CASES if args.backend in (case[0], "both")]


def measure_case(kind: str, poll_s: float, wake: bool, jobs: int, rng: random.Random) -> Case:
    return Case(kind, poll_s, wake, measure(kind, jobs, poll_s, wake, rng))


def report(case: Case) -> None:
    how = ("with its NOTIFY" if case.wake else "no wake-up but the commit (watched)" if case.backend == "sqlite"
           else "no wake-up (a lost message)")
    print(f"{case.backend}, {how}: inserted -> running, {len(case.latencies)} jobs: {summary(case.latencies)}",
          flush=True)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    rng = random.Random(args.seed)
    print(f"{machine()}; {args.jobs} jobs per case", flush=True)
    worst = 0.0
    for kind, poll_s, wake in cases(args):
        case = measure_case(kind, poll_s, wake, args.jobs, rng)
        report(case)
        worst = max(worst, case.worst)
    return 0 if worst <= TARGET_S else 1


if __name__ == "__main__":
    run_script(main)
