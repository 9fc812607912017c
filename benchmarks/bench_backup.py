"""Benchmark of `league backup` and `league restore` on a semester's database.

    python benchmarks/bench_backup.py [--backend sqlite|postgres] [--students 200] [--uploads 600]
                                      [--rounds 10] [--episodes 100] [--distinct 600] [--repeats 3]

Builds a semester through the API, as bench_rush.py's course does: --students students (a roster)
upload --uploads agents (its mix of formats and observations, --distinct different files, 10 %
broken), evaluated with --episodes episodes by two `league worker`s, then --rounds championship
rounds of every student in heats of 10 (each heat's replay stored). Then, with the server still
running, times the commands an administrator runs (each a new process, as from cron):
`league backup FILE` (--repeats times), and
`league restore FILE` into a fresh data directory (SQLite) or an empty database (PostgreSQL), of the
same backend and of the other one (the backup format is the same for both). Printed: the database's
size and rows, each command's wall time (median, range) and the file's size; checked, exit status 1
if one fails: every restore holds the backup's rows.
"""
from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _league import League, backend, enrol
from bench_league import new_championship, timed_round
from bench_rush import Uploader, broken_files, good_files, plan, wait_queue_empty

TABLES = ("users", "submissions", "blobs", "evaluations", "episode_results", "jobs", "races", "race_replays")


def build_semester(league: League, args: argparse.Namespace, folder: Path) -> None:
    (folder / "files").mkdir()
    uploads = plan(args.students, args.uploads, good_files(folder / "files", min(args.distinct, args.uploads)),
                   broken_files(folder / "files"), args.seed)
    with league.client() as instructor:
        tokens = enrol(instructor, [f"student{k:03d}" for k in range(args.students)])
    begin = time.perf_counter()
    Uploader(league, tokens, uploads, window_s=0.0).run()
    wait_queue_empty(league, 600 + args.uploads * args.episodes * 0.05)
    print(f"  {len(uploads)} uploads evaluated in {time.perf_counter() - begin:.0f} s", flush=True)
    begin = time.perf_counter()
    with league.client() as instructor:
        championship_id = new_championship(instructor, "semester cup", args.seed)
        for _ in range(args.rounds):
            timed_round(instructor, championship_id, timeout=120 + 20 * args.students)
    print(f"  {args.rounds} rounds raced in {time.perf_counter() - begin:.0f} s", flush=True)


def timed_command(league: League, *args: str, settings: dict[str, str] | None = None) -> tuple[float, str]:
    """Wall time of `python -m league.server ARGS` (a new process, as cron starts it) and its stderr."""
    begin = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "league.server", *args], env={**league.env, **(settings or {})},
                          cwd=league.root, capture_output=True, text=True, timeout=3600)
    seconds = time.perf_counter() - begin
    if done.returncode != 0:
        raise RuntimeError(f"league {' '.join(args)} failed:\n{done.stderr}")
    return seconds, done.stderr


def database_size(url: str) -> tuple[int, dict[str, int]]:
    """Bytes of the database (SQLite: its file, without the WAL) and rows of the league's tables."""
    from sqlalchemy import create_engine, text

    engine = create_engine(url)
    with engine.connect() as connection:
        rows = {table: connection.execute(text(f"SELECT count(*) FROM {table}")).scalar_one() for table in TABLES}
        size = (Path(url.removeprefix("sqlite:///")).stat().st_size if url.startswith("sqlite:///") else
                connection.execute(text("SELECT pg_database_size(current_database())")).scalar_one())
    engine.dispose()
    return size, rows


def spread(seconds: list[float]) -> str:
    return (f"{statistics.median(seconds):.1f} s ({min(seconds):.1f}-{max(seconds):.1f} s, {len(seconds)} runs)"
            if len(seconds) > 1 else f"{seconds[0]:.1f} s")


def measure(league: League, args: argparse.Namespace, folder: Path, database_url: str) -> list[str]:
    """Back up and restore; print the figures, return what failed."""
    mb = 2**20
    backup_file = folder / "semester.bak"
    runs = [timed_command(league, "backup", str(backup_file)) for _ in range(args.repeats)]
    size, rows = database_size(f"sqlite:///{backup_file}")
    print(f"  database: {database_size(database_url)[0] / mb:.1f} MB; rows: "
          f"{', '.join(f'{n} {table}' for table, n in rows.items())}", flush=True)
    print(f"  league backup FILE (the server running): {spread([s for s, _ in runs])}; the file "
          f"{size / mb:.1f} MB", flush=True)
    failures = []
    for target in (args.backend, "postgres" if args.backend == "sqlite" else "sqlite"):
        with tempfile.TemporaryDirectory(prefix="league-restore-") as tmp, backend(target, Path(tmp)) as urls:
            settings = {**urls, "LEAGUE_DATA_DIR": tmp}
            seconds, _ = timed_command(league, "restore", str(backup_file), settings=settings)
            where = "a fresh data directory (SQLite)" if target == "sqlite" else "an empty PostgreSQL database"
            restored_size, restored = database_size(urls["LEAGUE_DATABASE_URL"])
            print(f"  league restore FILE into {where}: {seconds:.1f} s; the database {restored_size / mb:.1f} MB",
                  flush=True)
            timed_command(league, "users", "list", settings=settings)  # the restored league opens
            if restored != rows:
                failures.append(f"restore into {target}: rows {restored}, the backup's {rows}")
    return failures


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite",
                        help="the semester's database: SQLite, or the local PostgreSQL (LEAGUE_BENCH_PG)")
    parser.add_argument("--students", type=int, default=200)
    parser.add_argument("--uploads", type=int, default=600)
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--episodes", type=int, default=100, help="episodes of each evaluation")
    parser.add_argument("--distinct", type=int, default=600,
                        help="different working agent files (a class's files all differ; the store keeps each once)")
    parser.add_argument("--repeats", type=int, default=3, help="backups timed")
    parser.add_argument("--seed", type=int, default=1)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    per_student = math.ceil(args.uploads / args.students)
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}, {os.cpu_count()} CPUs; {args.backend}: "
          f"{args.students} students, {args.uploads} uploads, {args.rounds} rounds, {args.episodes}-episode "
          f"evaluations", flush=True)
    with tempfile.TemporaryDirectory(prefix="league-semester-") as tmp, backend(args.backend, Path(tmp)) as urls:
        folder = Path(tmp)
        settings = {**urls, "LEAGUE_EVAL_EPISODES": str(args.episodes), "LEAGUE_EVAL_SEED": str(args.seed),
                    "LEAGUE_QUOTA_PER_DAY": str(per_student), "LEAGUE_MAX_JOBS_IN_FLIGHT": str(per_student),
                    "LEAGUE_CPU_SLOTS_DIR": str(folder / "cpu-slots")}
        with League(folder, embedded=False, workers=2, settings=settings) as league:
            build_semester(league, args, folder)
            failures = measure(league, args, folder, urls["LEAGUE_DATABASE_URL"])
    for failure in failures:
        print(f"  FAILED: {failure}", flush=True)
    print(f"checks: {'all passed' if not failures else f'{len(failures)} FAILED'} (every restore holds the "
          f"backup's rows)", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # cleanup (servers, temporary files) on SIGTERM too
    with contextlib.suppress(KeyboardInterrupt):
        sys.exit(main())
