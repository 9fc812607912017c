"""Benchmark of job coordination on PostgreSQL: many worker processes claiming no-op jobs.

    python benchmarks/bench_claims.py [--processes 16] [--owners 10000] [--depths 1000 10000] [--claims 3000]
                                      [--backend postgres|sqlite] [--paths first-turns ranking]

For each queue depth: a new database (the server's schema) holds that many queued jobs of
--owners students (jobs spread over them in turn); --processes processes, started together, each
claim the fairest queued job with league.server.jobs.leases.claim_next and complete it at once
(a no-op handler: the cost measured is the coordination only), until --claims jobs are done.
Printed: jobs/s (claim + complete), each claim's p50/p99 (empty-handed ones included), how many
claims came back empty while jobs were queued (all candidates taken by others: a worker would
drop that queue message), and the CPU time the PostgreSQL
processes used per job (read from /proc: the server runs on this machine, sharing its CPUs with
the claimers). Checked (exit status 1): no job claimed twice (by the claimers' records and by
the database: every job done once, with one attempt), nothing left running. `--backend sqlite`
runs the same on SQLite (no database CPU figure: SQLite runs inside the claimers).

Each depth is measured with each of --paths, side by side: `first-turns`, the claim as it is (the
first queued jobs that take their owner's first turn, read from an index, when there are enough:
leases.first_turns), and `ranking`, the claim it replaced (every queued and running job ranked per
claim: leases.ranked_queued alone).
"""
from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from _league import database, machine, percentiles_ms, run_script

NOOP = "noop"  # the default kind of the jobs (the NoOp handler runs whatever kind they have)
PATHS = ("first-turns", "ranking")
TARGET_CPU_MS = 5.0  # PostgreSQL CPU per claim at 10,000 queued: one core serves 200 claims/s


@dataclass
class Depth:
    """The figures of one queue depth, and what the audit found."""

    depth: int  # jobs queued at the start
    path: str  # one of PATHS
    claimed: int  # jobs claimed and completed
    double_claims: int
    wall_s: float
    misses: int  # claims that found no job while jobs were queued
    claim_ms: dict[str, float]  # p50, p99 of each claim (empty-handed ones included)
    database_cpu_s: float  # PostgreSQL's processes' CPU time (NaN on SQLite)
    failures: list[str] = field(default_factory=list)

    @property
    def jobs_per_s(self) -> float:
        return self.claimed / self.wall_s


class NoOp:
    """A job handler (league.server.jobs.runner.JobHandler) that does nothing."""

    parallel_sandboxes = False

    def begin(self, session, job) -> None:
        pass

    def finish(self, session, job, outcome) -> list[int]:
        return []

    def give_up(self, session, job, reason: str) -> None:
        pass


def fill(database_url: str, owners: int, jobs: int, kind: str = NOOP) -> None:
    """The schema, `owners` students, and `jobs` queued no-op jobs owned by them in turn; analysed."""
    from sqlalchemy import insert

    from league.server.db.models import Job, User
    from league.server.db.session import make_engine, make_sessionmaker, migrate

    engine = make_engine(database_url)
    try:
        migrate(engine)
        with make_sessionmaker(engine).begin() as session:
            session.execute(insert(User), [{"name": f"student{k:05d}", "role": "student"} for k in range(owners)])
            first = session.query(User.id).order_by(User.id).first()[0]
            session.execute(insert(Job), [{"kind": kind, "owner_id": first + k % owners} for k in range(jobs)])
        with engine.connect() as connection:  # the statistics a live database has (autovacuum keeps them)
            connection.exec_driver_sql("ANALYZE")
            connection.commit()
    finally:
        engine.dispose()


def claimer(database_url: str, path: str, kind: str, start, release, done, claims: int, results) -> None:
    """One worker process: claim and complete until `claims` jobs are done in all; reports
    (claimed ids, each claim's seconds, claims that found no job though jobs were queued)."""
    from league.server.db.session import make_engine, make_sessionmaker
    from league.server.jobs import leases

    if path == "ranking":  # the claim before the index: every claim ranks every queued and running job
        leases.first_turns = lambda session, limit: []

    engine = make_engine(database_url)
    sessions, handlers = make_sessionmaker(engine), {kind: NoOp()}
    with sessions() as session:  # connected before the start: the connection is not timed
        session.connection()
    claimed, seconds, misses, in_a_row = [], [], 0, 0
    start.wait()
    while True:
        with done.get_lock():
            if done.value >= claims:
                break
            done.value += 1
        attempt_id = f"{os.getpid()}/{uuid.uuid4().hex[:8]}"
        begin = time.perf_counter()
        job = leases.claim_next(sessions, handlers, attempt_id=attempt_id)
        seconds.append(time.perf_counter() - begin)
        if job is None:  # every candidate was taken by others meanwhile (or the queue is empty)
            with done.get_lock():
                done.value -= 1
            misses, in_a_row = misses + 1, in_a_row + 1
            if in_a_row > 100:
                break
            continue
        in_a_row = 0
        leases.complete(sessions, handlers, job_id=job.id, attempt_id=attempt_id, outcome=None)
        claimed.append(job.id)
    results.put((claimed, seconds, misses))
    release.wait()  # the parent reads the PostgreSQL processes' CPU time while this connection lives
    engine.dispose()


def postgres_cpu_s() -> float:
    """CPU seconds (user + system) of the processes named postgres on this machine."""
    tick, total = os.sysconf("SC_CLK_TCK"), 0
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            continue
        name, fields = stat[stat.index("(") + 1:stat.rindex(")")], stat[stat.rindex(")") + 2:].split()
        if name == "postgres":
            total += int(fields[11]) + int(fields[12])
    return total / tick


def measure(database_url: str, path: str, kind: str, processes: int,
            claims: int) -> tuple[float, list[int], list[float], int, float]:
    """Wall seconds, the claimed ids, each claim's seconds, misses, and the PostgreSQL processes' CPU
    seconds meanwhile (NaN on SQLite)."""
    postgres = database_url.startswith("postgresql")
    context = multiprocessing.get_context("spawn")
    start, release, done, results = context.Event(), context.Event(), context.Value("i", 0), context.Queue()
    workers = [context.Process(target=claimer, args=(database_url, path, kind, start, release, done, claims, results))
               for _ in range(processes)]
    for worker in workers:
        worker.start()
    try:
        time.sleep(3 + 0.5 * processes)  # every process imported and connected
        cpu_before, begin = postgres_cpu_s() if postgres else math.nan, time.perf_counter()
        start.set()
        reports = [results.get(timeout=600) for _ in workers]
        wall = time.perf_counter() - begin
        cpu = postgres_cpu_s() - cpu_before if postgres else math.nan
    finally:
        release.set()
        for worker in workers:
            worker.join(timeout=60)
            if worker.is_alive():
                worker.kill()
    claimed = [job_id for ids, _, _ in reports for job_id in ids]
    seconds = [s for _, times, _ in reports for s in times]
    return wall, claimed, seconds, sum(misses for _, _, misses in reports), cpu


def audit(database_url: str, claimed: list[int]) -> list[str]:
    from sqlalchemy import select

    from league.server.db.models import Job
    from league.server.db.session import make_engine, make_sessionmaker

    engine = make_engine(database_url)
    try:
        with make_sessionmaker(engine)() as session:
            rows = session.execute(select(Job.id, Job.status, Job.attempts)).all()
    finally:
        engine.dispose()
    failures = []
    if len(claimed) != len(set(claimed)):
        failures.append(f"{len(claimed) - len(set(claimed))} jobs claimed twice by the processes' records")
    done = {row.id for row in rows if row.status == "done"}
    if done != set(claimed):
        failures.append(f"done in the database: {len(done)} jobs; claimed: {len(set(claimed))}")
    failures += [f"job {row.id}: {row.status}, {row.attempts} attempts" for row in rows
                 if (row.status, row.attempts) not in (("done", 1), ("queued", 0))]
    return failures[:20]


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--processes", type=int, default=16)
    parser.add_argument("--owners", type=int, default=10000, help="students owning the queued jobs")
    parser.add_argument("--depths", type=int, nargs="+", default=[1000, 10000], help="queued jobs at the start")
    parser.add_argument("--claims", type=int, default=3000, help="jobs claimed per depth (at most the depth)")
    parser.add_argument("--backend", choices=["postgres", "sqlite"], default="postgres")
    parser.add_argument("--paths", choices=PATHS, nargs="+", default=list(PATHS),
                        help="the claim as it is (first-turns), the one it replaced (ranking)")
    parser.add_argument("--kind", default=NOOP, help="the jobs' kind: a claim looks for validations, then "
                                                     "evaluations, then the other kinds (e.g. validate, as "
                                                     "a deadline's uploads)")
    return parser.parse_args(argv)


def measure_depth(args: argparse.Namespace, depth: int, path: str) -> Depth:
    with tempfile.TemporaryDirectory(prefix="league-claims-") as tmp, database(args.backend, Path(tmp)) as url:
        fill(url, args.owners, depth, args.kind)
        wall, claimed, seconds, misses, cpu = measure(url, path, args.kind, args.processes, min(args.claims, depth))
        found = audit(url, claimed)
    return Depth(depth=depth, path=path, claimed=len(claimed), double_claims=len(claimed) - len(set(claimed)),
                 wall_s=wall, misses=misses, claim_ms=percentiles_ms(seconds), database_cpu_s=cpu, failures=found)


def report(figures: Depth) -> None:
    f = figures
    cpu = ("" if math.isnan(f.database_cpu_s) else
           f"; PostgreSQL CPU {1000 * f.database_cpu_s / max(1, f.claimed):.2f} ms per job ({f.database_cpu_s:.1f} s "
           f"in all)")
    print(f"  queue of {f.depth} jobs, {f.path:>11}: {f.claimed} claimed and completed in {f.wall_s:.2f} s: "
          f"{f.jobs_per_s:.0f} jobs/s; {f.misses} claims found no job while jobs were queued; a claim p50 "
          f"{f.claim_ms['p50']:.1f} ms, p99 {f.claim_ms['p99']:.1f} ms{cpu}; double claims: {f.double_claims}"
          f"{'' if not f.failures else '; FAILED: ' + '; '.join(f.failures)}", flush=True)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    where = "PostgreSQL" if args.backend == "postgres" else "SQLite"
    print(f"{machine()}; {args.processes} processes claiming no-op jobs (kind {args.kind}) of {args.owners} students "
          f"(leases.claim_next + complete) on {where}", flush=True)
    failures = []
    for depth in args.depths:
        for path in args.paths:
            figures = measure_depth(args, depth, path)
            report(figures)
            failures += figures.failures
            if depth >= 10_000 and path == PATHS[0] and not math.isnan(figures.database_cpu_s):
                per_claim = 1000 * figures.database_cpu_s / max(1, figures.claimed)
                print(f"    target <= {TARGET_CPU_MS:g} ms of PostgreSQL CPU per claim at 10,000 queued: "
                      f"{'ok' if per_claim <= TARGET_CPU_MS else 'OVER TARGET'}", flush=True)
    print(f"checks: {'all passed' if not failures else f'{len(failures)} FAILED'} (no job claimed twice, "
          f"every claimed job done once)", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    run_script(main)
