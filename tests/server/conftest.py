"""Fixtures of the server tests: real databases (SQLite, PostgreSQL; each is also its league's job
queue), the test settings, the model files the tests upload, and the HTTP helpers that speak to a
league whether it runs in this process (tests/server/api/conftest.py) or as `league serve` and
`league worker` processes (tests/system/servers.py: only the system tests start those).

PostgreSQL (127.0.0.1:5432, user postgres, trust auth) must be running for the "postgres"
parameter; each league gets a database of its own, dropped at the end.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

import httpx
import pytest

from league import testing as mf

REPO = Path(__file__).resolve().parents[2]
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
    # the tests read boards as visitors; tests/server/api/routes/test_privacy.py the rest
    "LEAGUE_BOARD_VISIBILITY": "public",
}


# --------------------------------------------------------------------------- backends


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


@pytest.fixture(params=BACKENDS)
def backend(request, tmp_path):
    with fresh_backend(request.param, tmp_path) as database_url:
        yield request.param, database_url


# --------------------------------------------------------------------------- commands


def server_command(cwd: Path, *args: str, **env: str) -> subprocess.CompletedProcess:
    """`python -m league.server ARGS` in `cwd`, with no LEAGUE_* variable but `env`'s (as a shell
    without the test settings)."""
    clean = {name: value for name, value in os.environ.items() if not name.upper().startswith("LEAGUE_")}
    return subprocess.run([sys.executable, "-m", "league.server", *args], cwd=cwd, capture_output=True, text=True,
                          env={**clean, "PYTHONPATH": str(REPO), **env}, timeout=120)


# --------------------------------------------------------------------------- helpers


TERMINAL = {"ready", "rejected", "failed"}


def wait_for(fetch, done, timeout: float = 90, interval: float = 0.1):
    """Poll `fetch()` until `done(value)`; return the value (fail with the last one on timeout)."""
    deadline = time.monotonic() + timeout
    value = fetch()
    while not done(value):
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s; last value: {value}")
        time.sleep(interval)
        value = fetch()
    return value


def submission(client: httpx.Client, submission_id: int) -> dict:
    response = client.get(f"/api/submissions/{submission_id}")
    assert response.status_code == 200, response.text
    return response.json()


def episodes(client: httpx.Client, submission_id: int, evaluation_id: int, limit: int = 1000) -> list[dict]:
    """Every episode of an evaluation, page after page (the status answer carries none)."""
    items: list[dict] = []
    while True:
        response = client.get(f"/api/submissions/{submission_id}/episodes",
                              params={"evaluation_id": evaluation_id, "offset": len(items), "limit": limit})
        assert response.status_code == 200, response.text
        page = response.json()
        assert page["evaluation_id"] == evaluation_id
        items += page["items"]
        if len(items) >= page["total"] or not page["items"]:
            return items


def settled(value: dict) -> bool:
    """Validation finished, and if the submission is ready, its evaluation too."""
    if value["status"] not in TERMINAL:
        return False
    return value["status"] != "ready" or (value["evaluation"] or {}).get("status") in ("done", "failed")


def wait_settled(client: httpx.Client, submission_id: int, timeout: float = 90) -> dict:
    return wait_for(lambda: submission(client, submission_id), settled, timeout)


def upload(client: httpx.Client, path: Path, name: str | None = None) -> httpx.Response:
    with open(path, "rb") as handle:
        return client.post("/api/submissions", files={"file": (path.name, handle)},
                           data={"name": name or path.stem})


def create_student(league, name: str) -> httpx.Client:
    """A new student of `league` (in process, or a LeagueServer), as a client holding their token."""
    with league.client(league.instructor_token) as instructor:
        response = instructor.post("/api/users", json={"name": name})
    assert response.status_code == 201, response.text
    return league.client(response.json()["token"])


@pytest.fixture(scope="session")
def models(tmp_path_factory) -> dict[str, Path]:
    """Every model file the tests upload, built once."""
    d = tmp_path_factory.mktemp("server-models")
    from league.agents import export_onnx, export_torchscript

    from league.testing import thesis_driver

    good_onnx = export_onnx(thesis_driver(), d / "thesis_actor.onnx")
    return {
        "onnx": good_onnx,
        "torchscript": export_torchscript(thesis_driver(), d / "thesis_actor.pt"),
        "heuristic_onnx": mf.onnx_heuristic(d / "heuristic.onnx"),
        "random_bytes": mf.random_bytes(d / "random.onnx"),
        "truncated": mf.truncated(good_onnx, d / "truncated.onnx"),
        "pickle_pt": mf.pickle_renamed_pt(d / "checkpoint.pt"),
        "wrong_input": mf.onnx_mlp(d / "input7.onnx", in_dim=7),
        "wrong_output": mf.onnx_mlp(d / "output3.onnx", out_dim=3),
        "nan": mf.onnx_mlp(d / "nan.onnx", nan=True),
        "loop": mf.torchscript_loop(d / "loop.pt"),
        "slow": mf.onnx_slow(d / "slow.onnx"),
        "memory_hog": mf.onnx_memory_hog(d / "hog.onnx"),
        "external_data": mf.onnx_external_data(d / "external.onnx"),
        "custom_domain": mf.onnx_custom_domain(d / "custom.onnx"),
        "reads_file": mf.torchscript_reads_file(d / "reads_file.pt"),
    }


# --------------------------------------------------------------------------- races


def post_race(client: httpx.Client, ids: list[int], **body) -> httpx.Response:
    return client.post("/api/races", json={"submission_ids": ids, **body})


def not_raceable(submission_id: int) -> dict:
    """The one answer for a submission that does not exist, is private, or is of another course."""
    return {"detail": f"no submission {submission_id} you may race: your own, the baselines, or another student's "
                      "agent once its owner makes it public"}
