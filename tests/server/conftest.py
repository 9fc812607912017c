"""Fixtures of the server tests: real databases (SQLite, PostgreSQL; each is also its league's job
queue), real servers started as `python -m league.server serve|worker` subprocesses, spoken to over HTTP.

PostgreSQL (127.0.0.1:5432, user postgres, trust auth) must be running for the "postgres"
parameter; each server gets a database of its own, dropped at the end.
"""
from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass, field
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


# --------------------------------------------------------------------------- servers


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@dataclass
class LeagueServer:
    """A league started by hand the way its users start it: `serve` and `worker` subprocesses."""

    env: dict[str, str]
    data_dir: Path
    port: int = field(default_factory=free_port)
    api: subprocess.Popen | None = None
    workers: list[subprocess.Popen] = field(default_factory=list)
    instructor_token: str = ""
    root: Path = REPO  # the source tree it runs (with PYTHONPATH: another release's, to upgrade from)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def command(self, *args: str, **kwargs) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "league.server", *args], env=self.env, cwd=self.root,
                              capture_output=True, text=True, timeout=120, **kwargs)

    def _spawn(self, *args: str, log_name: str, prefix: tuple[str, ...] = (), **env: str) -> subprocess.Popen:
        log = open(self.data_dir / log_name, "ab")
        return subprocess.Popen([*prefix, sys.executable, "-m", "league.server", *args], env={**self.env, **env},
                                cwd=self.root, stdout=log, stderr=subprocess.STDOUT)

    def start_api(self, embedded_worker: bool = True) -> None:
        args = ["serve", "--port", str(self.port)] + ([] if embedded_worker else ["--no-worker"])
        self.api = self._spawn(*args, log_name="api.log")
        self.wait_healthy()

    def start_worker(self, prefix: tuple[str, ...] = (), **env: str) -> subprocess.Popen:
        """A `league worker`; give LEAGUE_DATA_DIR to make it one "on another machine" (its own disk),
        and a `prefix` to start it otherwise (`ip netns exec NAME`: in a network namespace)."""
        worker = self._spawn("worker", log_name=f"worker-{len(self.workers)}.log", prefix=prefix, **env)
        self.workers.append(worker)
        return worker

    def wait_healthy(self, timeout: float = 60) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.api.poll() is not None:
                raise RuntimeError(f"the server exited ({self.api.returncode}):\n{self.log('api.log')}")
            with contextlib.suppress(httpx.HTTPError):
                if httpx.get(f"{self.url}/api/health", timeout=2).status_code == 200:
                    return
            time.sleep(0.1)
        raise TimeoutError(f"the server did not answer in {timeout} s:\n{self.log('api.log')}")

    def log(self, name: str) -> str:
        path = self.data_dir / name
        return path.read_text(errors="replace")[-4000:] if path.exists() else ""

    def stop(self, process: subprocess.Popen | None, kill: bool = False) -> None:
        if process is None or process.poll() is not None:
            return
        process.send_signal(signal.SIGKILL if kill else signal.SIGTERM)
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()

    def stop_all(self) -> None:
        for worker in self.workers:
            self.stop(worker)
        self.stop(self.api)

    def client(self, token: str | None = None) -> httpx.Client:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.Client(base_url=self.url, headers=headers, timeout=30)


def server_command(cwd: Path, *args: str, **env: str) -> subprocess.CompletedProcess:
    """`python -m league.server ARGS` in `cwd`, with no LEAGUE_* variable but `env`'s (as a shell
    without the test settings)."""
    clean = {name: value for name, value in os.environ.items() if not name.upper().startswith("LEAGUE_")}
    return subprocess.run([sys.executable, "-m", "league.server", *args], cwd=cwd, capture_output=True, text=True,
                          env={**clean, "PYTHONPATH": str(REPO), **env}, timeout=120)


def make_server(tmp_path: Path, database_url: str, **settings: str) -> LeagueServer:
    data_dir = tmp_path / "data"
    data_dir.mkdir()
    env = {**os.environ, **TEST_SETTINGS, **settings, "LEAGUE_DATA_DIR": str(data_dir),
           "LEAGUE_DATABASE_URL": database_url,
           "LEAGUE_CPU_SLOTS_DIR": str(tmp_path / "cpu-slots"),  # this test's workers are one machine's
           "LEAGUE_BASELINES_DIR": str(data_dir / "baselines"),  # empty: the heuristic driver is the baseline
           "PYTHONPATH": str(REPO)}
    server = LeagueServer(env, data_dir)
    added = server.command("init", "--instructor", "prof")
    assert added.returncode == 0, added.stderr
    server.instructor_token = added.stdout.strip()
    return server


@pytest.fixture(scope="package", params=BACKENDS)
def league_server(request, tmp_path_factory):
    """A running `league serve` (API + its worker process) per backend, shared by the API tests."""
    tmp_path = tmp_path_factory.mktemp(f"league-{request.param}")
    with fresh_backend(request.param, tmp_path) as database_url:
        server = make_server(tmp_path, database_url)
        server.start_api()
        try:
            yield server
        finally:
            server.stop_all()


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


def create_student(server: LeagueServer, name: str) -> httpx.Client:
    with server.client(server.instructor_token) as instructor:
        response = instructor.post("/api/users", json={"name": name})
    assert response.status_code == 201, response.text
    return server.client(response.json()["token"])


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


# --------------------------------------------------------------------------- races and championships


def upload_ready(client: httpx.Client, path: Path, name: str | None = None, timeout: float = 90) -> dict:
    """Upload a good model and wait until it is ready and evaluated; return the submission."""
    response = upload(client, path, name)
    assert response.status_code == 201, response.text
    result = wait_settled(client, response.json()["id"], timeout)
    assert result["status"] == "ready", result["error"]
    return result


def baseline_submission(server: LeagueServer) -> dict:
    """The bundled `heuristic` agent of the `baselines` user, once ready and evaluated."""
    with server.client(server.instructor_token) as instructor:
        listing = instructor.get("/api/submissions", params={"all": True}).json()
        baseline = next(s for s in listing if s["owner"] == "baselines" and s["name"] == "heuristic")
        return wait_settled(instructor, baseline["id"])


def wait_race(client: httpx.Client, race_id: int, timeout: float = 120) -> dict:
    """GET /api/races/{id} until the race is done or failed."""
    def fetch() -> dict:
        response = client.get(f"/api/races/{race_id}")
        assert response.status_code == 200, response.text
        return response.json()

    return wait_for(fetch, lambda race: race["status"] in ("done", "failed"), timeout, interval=0.2)


def stored_model(server: LeagueServer, submission_: dict, directory: Path) -> Path:
    """A copy of the bytes the server keeps for a submission (what its races ran), named by kind."""
    digest = submission_["sha256"]
    suffix = ".onnx" if submission_["kind"] == "onnx" else ".pt"
    path = directory / f"submission-{submission_['id']}{suffix}"
    path.write_bytes((server.data_dir / "blobs" / digest[:2] / digest).read_bytes())
    return path


def race_locally(served_race: dict, files: dict[int, Path]):
    """The served race raced again in this process with the toolkit: same model files (by submission
    id), the stored seed and env options, the server's car names."""
    from league.agents import load_agent
    from league.evaluation import race

    entrants = served_race["entrants"]
    agents = [load_agent(files[e["submission_id"]]) for e in entrants]
    names = [f"{e['name']} ({e['owner']})" for e in entrants]
    return race(agents, seed=served_race["seed"], names=names, **served_race["env_options"])


def assert_same_classification(served: list[dict], local: list[dict]) -> None:
    """Same order, cars, outcomes and reasons; times and distances to 1e-9."""
    assert [(r["position"], r["car"], r["outcome"], r["reason"]) for r in served] == \
        [(r["position"], r["car"], r["outcome"], r["reason"]) for r in local]
    for mine, theirs in zip(served, local):
        assert mine["time"] == pytest.approx(theirs["time"], abs=1e-9), (mine, theirs)
        assert mine["distance"] == pytest.approx(theirs["distance"], abs=1e-9), (mine, theirs)


def add_user_in_new_course(server: LeagueServer, name: str, course_name: str, role: str = "student") -> str:
    """A user of another course, written straight into the server's database (the API has no
    way to create a second course); returns the user's token."""
    from league.server.db import crud
    from league.server.db.session import make_engine, make_sessionmaker

    engine = make_engine(server.env["LEAGUE_DATABASE_URL"])
    try:
        with make_sessionmaker(engine)() as session:
            course = crud.get_or_create_course(session, name=course_name,
                                               evaluation={"seed": 0, "episodes": 3, "env_options": {}})
            _, token = crud.create_user(session, name=name, role=role, course=course)
            session.commit()
    finally:
        engine.dispose()
    return token
