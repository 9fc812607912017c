"""What SQLite's secure_delete (league.server.db.session: an erased student's rows zeroed in the file)
costs the league's writes.

    python benchmarks/bench_secure_delete.py [--rows 20000] [--rounds 2]

A WAL database with the server's pragmas and a jobs-like table; --rows rows inserted, each updated
twice as a job goes queued -> running -> done (its texts shrinking: the freed bytes are what
secure_delete zeroes), a quarter deleted; one commit per statement, as the server writes. Printed:
the seconds of each round with secure_delete OFF and ON, alternated (the machine's noise shows in
their spread).
"""
from __future__ import annotations

import argparse
import sqlite3
import tempfile
import time
from pathlib import Path


def run(secure_delete: str, rows: int, directory: Path) -> float:
    connection = sqlite3.connect(directory / f"bench-{secure_delete}-{time.monotonic_ns()}.db", isolation_level=None)
    for pragma in ("journal_mode=WAL", "synchronous=NORMAL", "foreign_keys=ON", f"secure_delete={secure_delete}"):
        connection.execute(f"PRAGMA {pragma}")
    connection.execute("CREATE TABLE jobs (id INTEGER PRIMARY KEY, status TEXT, error TEXT, log TEXT)")
    started = time.perf_counter()
    for _ in range(rows):
        connection.execute("INSERT INTO jobs (status, log) VALUES ('queued', ?)", ("x" * 200,))
    for job in range(1, rows + 1):
        connection.execute("UPDATE jobs SET status = 'running', log = ? WHERE id = ?", ("y" * 100, job))
        connection.execute("UPDATE jobs SET status = 'done', log = ? WHERE id = ?", ("z" * 50, job))
    for job in range(1, rows // 4 + 1):
        connection.execute("DELETE FROM jobs WHERE id = ?", (job,))
    elapsed = time.perf_counter() - started
    connection.close()
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=20_000)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as directory:
        times = {"OFF": [], "ON": []}
        for _ in range(args.rounds):
            for mode in times:
                times[mode].append(run(mode, args.rows, Path(directory)))
    writes = args.rows * 3 + args.rows // 4
    for mode, seconds in times.items():
        print(f"secure_delete={mode:<3}  {writes} writes: " + ", ".join(f"{s:.2f} s" for s in seconds))


if __name__ == "__main__":
    main()
