"""Benchmark of `league backup` and `league restore` on a semester's database.

    python benchmarks/bench_backup.py [--backend sqlite|postgres] [--students 200] [--uploads 600]
                                      [--rounds 10] [--episodes 100] [--distinct 600] [--repeats 3]
                                      [--restore-into both|same]

Builds a semester through the API, as bench_rush.py's course does: --students students (a roster)
upload --uploads agents (its mix of formats and observations, --distinct different files, 10 %
broken), evaluated with --episodes episodes by two `league worker`s, then --rounds championship
rounds of every student in heats of 10 (each heat's replay stored). Then, with the server still
running, times the commands an administrator runs (each a new process, as from cron): `league
backup FILE` (--repeats times), and `league restore FILE` into a fresh data directory (SQLite) or
an empty database (PostgreSQL), of the same backend and of the other one (the backup format is the
same for both; `--restore-into same`: only the same). Printed: the database's size and rows, each
command's wall time (median, range) and the file's size; checked, exit status 1 if one fails:
every restore holds the backup's rows.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from _league import (
    League, backend, broken_files, checks_line, course_files, course_league, course_settings, enrol, machine,
    run_script, student_names, wait_queue_empty,
)
from bench_league import new_championship, timed_round
from bench_rush import Uploader, plan

TABLES = ("users", "submissions", "blobs", "evaluations", "episode_results", "jobs", "races", "race_replays")


MB = 2**20


@dataclass
class BackupFigures:
    """What backing up and restoring a semester measured, and what the checks found."""

    evaluated_s: float  # the uploads evaluated (building the semester)
    rounds_s: float  # its rounds raced
    database_mb: float
    rows: dict[str, int]  # the backup's rows per table
    backup_s: list[float]  # each `league backup FILE`
    backup_mb: float  # the file
    restores: dict[str, dict[str, float]] = field(default_factory=dict)  # backend -> seconds, database_mb
    failures: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return not self.failures


def build_semester(league: League, args: argparse.Namespace, folder: Path) -> tuple[float, float]:
    """The course's uploads evaluated, then its rounds raced: the seconds of each."""
    uploads = plan(args.students, args.uploads, course_files(folder / "files", min(args.distinct, args.uploads)),
                   broken_files(folder / "files"), args.seed)
    with league.client() as instructor:
        tokens = enrol(instructor, student_names(args.students))
    begin = time.perf_counter()
    Uploader(league, tokens, uploads, window_s=0.0).run()
    wait_queue_empty(league, 600 + args.uploads * args.episodes * 0.05)
    evaluated = time.perf_counter() - begin
    begin = time.perf_counter()
    with league.client() as instructor:
        championship_id = new_championship(instructor, "semester cup", args.seed)
        for _ in range(args.rounds):
            timed_round(instructor, championship_id, timeout=120 + 20 * args.students)
    return evaluated, time.perf_counter() - begin


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


def backup_and_restore(league: League, args: argparse.Namespace, folder: Path, database_url: str,
                       built: tuple[float, float]) -> BackupFigures:
    """Back up (--repeats times) and restore into each target; the figures, and what failed."""
    backup_file = folder / "semester.bak"
    runs = [timed_command(league, "backup", str(backup_file))[0] for _ in range(args.repeats)]
    size, rows = database_size(f"sqlite:///{backup_file}")
    figures = BackupFigures(evaluated_s=built[0], rounds_s=built[1], database_mb=database_size(database_url)[0] / MB,
                            rows=rows, backup_s=runs, backup_mb=size / MB)
    other = "postgres" if args.backend == "sqlite" else "sqlite"
    for target in (args.backend, other) if args.restore_into == "both" else (args.backend,):
        with tempfile.TemporaryDirectory(prefix="league-restore-") as tmp, backend(target, Path(tmp)) as urls:
            settings = {**urls, "LEAGUE_DATA_DIR": tmp}
            seconds, _ = timed_command(league, "restore", str(backup_file), settings=settings)
            restored_size, restored = database_size(urls["LEAGUE_DATABASE_URL"])
            figures.restores[target] = {"seconds": seconds, "database_mb": restored_size / MB}
            timed_command(league, "users", "list", settings=settings)  # the restored league opens
            if restored != rows:
                figures.failures.append(f"restore into {target}: rows {restored}, the backup's {rows}")
    return figures


def report(figures: BackupFigures) -> None:
    f = figures
    print(f"  uploads evaluated in {f.evaluated_s:.0f} s; rounds raced in {f.rounds_s:.0f} s")
    print(f"  database: {f.database_mb:.1f} MB; rows: {', '.join(f'{n} {table}' for table, n in f.rows.items())}")
    print(f"  league backup FILE (the server running): {spread(f.backup_s)}; the file {f.backup_mb:.1f} MB")
    for target, restore in f.restores.items():
        where = "a fresh data directory (SQLite)" if target == "sqlite" else "an empty PostgreSQL database"
        print(f"  league restore FILE into {where}: {restore['seconds']:.1f} s; the database "
              f"{restore['database_mb']:.1f} MB")
    print(checks_line(f.failures, "every restore holds the backup's rows"), flush=True)


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
    parser.add_argument("--restore-into", choices=["both", "same"], default="both",
                        help="restore into both backends (default), or only the semester's own")
    return parser.parse_args(argv)


def measure(args: argparse.Namespace) -> BackupFigures:
    """The semester of `args` (parse()'s options) on a league of its own, backed up and restored."""
    settings = course_settings(students=args.students, uploads=args.uploads, episodes=args.episodes, seed=args.seed)
    with course_league(args.backend, "league-semester-", **settings) as (league, folder, database_url):
        built = build_semester(league, args, folder)
        return backup_and_restore(league, args, folder, database_url, built)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    print(f"{machine()}; {args.backend}: {args.students} students, {args.uploads} uploads, {args.rounds} rounds, "
          f"{args.episodes}-episode evaluations", flush=True)
    figures = measure(args)
    report(figures)
    return 0 if figures.passed else 1


if __name__ == "__main__":
    run_script(main)
