"""The databases of the server tests, real ones of each backend (SQLite, PostgreSQL; each is also its
league's job queue), and the test settings.

PostgreSQL (127.0.0.1:5432, user postgres, trust auth) must be running for the "postgres"
backend; each league gets a database of its own, dropped at the end.
"""
from __future__ import annotations

import contextlib
import os
import uuid
from pathlib import Path

import pytest

PG_ADMIN_URL = os.environ.get("LEAGUE_TEST_PG", "postgresql://postgres@127.0.0.1:5432/test")
BACKENDS = ["sqlite", "postgres"]
# Small, fast settings: 3-episode evaluations, short leases so that a dead worker is noticed in seconds.
TEST_SETTINGS = {
    "LEAGUE_EVAL_EPISODES": "3",
    "LEAGUE_EVAL_SEED": "11",
    "LEAGUE_MAX_UPLOAD_MB": "5",
    "LEAGUE_QUOTA_PER_DAY": "4",
    "LEAGUE_MAX_JOBS_IN_FLIGHT": "20",  # tests upload faster than a worker evaluates
    "LEAGUE_FIRST_CALL_ALLOWANCE_MS": "500",
    "LEAGUE_LOAD_CPU_S": "8",
    "LEAGUE_HEARTBEAT_INTERVAL_S": "0.5",
    "LEAGUE_LEASE_TIMEOUT_S": "3",
    "LEAGUE_REAPER_INTERVAL_S": "0.5",
    "LEAGUE_WORKER_HEARTBEAT_S": "0.5",
    "LEAGUE_WORKER_THREADS": "2",
}  # the board visibility is the default (members): a test reads boards logged in, or sets it itself


def _postgres_available() -> str | None:
    try:
        import psycopg

        psycopg.connect(PG_ADMIN_URL, connect_timeout=3).close()
    except Exception as error:  # noqa: BLE001 - any failure means "not available here"
        return f"PostgreSQL not reachable: {error}"
    return None


@contextlib.contextmanager
def fresh_backend(kind: str, directory: Path):
    """The URL of a new, empty database; removed afterwards."""
    name = f"league_test_{uuid.uuid4().hex[:10]}"
    if kind == "sqlite":
        yield f"sqlite:///{directory / 'league.db'}"
        return
    reason = _postgres_available()
    if reason:
        pytest.skip(reason)
    import psycopg

    with psycopg.connect(PG_ADMIN_URL, autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
    try:
        yield f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"
    finally:
        with psycopg.connect(PG_ADMIN_URL, autocommit=True) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
