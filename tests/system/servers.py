"""Leagues as their users start them: `python -m league.server serve|worker` subprocesses on a real
database of each backend, with the test settings, spoken to over HTTP; and what the system tests do
with them (ready agents, races raced again locally, users of another course).

Only the system tests start these (tests/conftest.py refuses a test elsewhere that imports this
module); the unit tests of the API run the app in process (tests/server/api/in_process.py).
"""
from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import pytest

from ..server.api_calls import settled, unique, upload, wait_for, wait_settled
from ..server.backends import TEST_SETTINGS, fresh_backend
from ..server.commands import REPO


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def freeze(pid: int) -> None:
    """SIGSTOP `pid` and return once every thread of it has stopped: kill() returns before then, and a
    thread still running might, say, touch a file or take a lock just after the caller's next step."""
    os.kill(pid, signal.SIGSTOP)
    tasks = Path(f"/proc/{pid}/task")

    def state(task: Path) -> str:  # the field after "(comm)", which may itself hold spaces
        return (task / "stat").read_text().rpartition(")")[2].split()[0]
    wait_for(lambda: {state(task) for task in tasks.iterdir()}, lambda states: states <= {"T", "t"},
             timeout=10, interval=0.01)


def embedded_worker(api: subprocess.Popen) -> int:
    """The pid of the worker process a `league serve` started (by its supervising thread: each thread's
    children are listed under it)."""
    tasks = Path(f"/proc/{api.pid}/task").iterdir()
    children = [pid for task in tasks for pid in (task / "children").read_text().split()]
    return next(int(pid) for pid in children if b"worker" in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0"))


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
        self.wait_healthy(ready=("ok",) if embedded_worker else ("ok", "degraded"))

    def start_worker(self, prefix: tuple[str, ...] = (), **env: str) -> subprocess.Popen:
        """A `league worker`; give LEAGUE_DATA_DIR to make it one "on another machine" (its own disk),
        and a `prefix` to start it otherwise (`ip netns exec NAME`: in a network namespace)."""
        worker = self._spawn("worker", log_name=f"worker-{len(self.workers)}.log", prefix=prefix, **env)
        self.workers.append(worker)
        return worker

    def wait_healthy(self, timeout: float = 60, ready: tuple[str, ...] = ("ok",)) -> None:
        """Until /api/health's status is one of `ready`: "ok" once a worker beats, "degraded" (503) for an
        API that answers with no worker yet (--no-worker)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.api.poll() is not None:
                raise RuntimeError(f"the server exited ({self.api.returncode}):\n{self.log('api.log')}")
            with contextlib.suppress(httpx.HTTPError, ValueError, KeyError):
                if httpx.get(f"{self.url}/api/health", timeout=2).json()["status"] in ready:
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


def make_server(tmp_path: Path, database_url: str, **settings: str) -> LeagueServer:
    """A new league on `database_url` with the test settings (and `settings`), its data in
    tmp_path/data and an instructor `prof`; nothing started yet."""
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


@contextlib.contextmanager
def running_server(directory: Path, backend: str):
    """A `league serve` (API and its worker process) on a new database of `backend`, stopped after."""
    with fresh_backend(backend, directory) as database_url:
        server = make_server(directory, database_url)
        server.start_api()
        try:
            yield server
        finally:
            server.stop_all()


# --------------------------------------------------------------------------- what the tests do with them


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


def student_token(server, name: str) -> str:
    """A new student of the shared course (its instructor creates them); returns their token."""
    with server.client(server.instructor_token) as instructor:
        response = instructor.post("/api/users", json={"name": name})
    assert response.status_code == 201, response.text
    return response.json()["token"]


def instructor_of_a_new_course(server) -> str:
    """An instructor of a course of their own: their students, settings and re-runs change nothing
    another test sees (re-running the shared course's evaluations kept the worker busy for later tests)."""
    return add_user_in_new_course(server, unique("prof"), unique("course"), role="instructor")


def wait_for_the_baselines(server) -> None:
    """Until the first start's baselines are evaluated, as users find the league after `league serve`:
    a test that came first would otherwise see (and the public cache keep) a league without them."""
    with server.client(server.instructor_token) as instructor:
        wait_for(lambda: instructor.get("/api/submissions?all=true").json(),
                 lambda submissions: submissions and all(settled(s) for s in submissions))
