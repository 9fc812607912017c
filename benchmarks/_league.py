"""Set-up shared by the benchmarks: a league of servers, a course's students and agent files, timing helpers.

Everything runs on this machine: servers started as `python -m league.server serve|worker`
subprocesses on 127.0.0.1, in a temporary data directory, with bounded request loops. The model
files come from `league.testing` (the tests' builders, shipped with the package).
"""
from __future__ import annotations

import contextlib
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

PG_ADMIN_URL = os.environ.get("LEAGUE_BENCH_PG", "postgresql://postgres@127.0.0.1:5432/test")


def machine() -> str:
    """This machine's load and CPUs: the first line of a benchmark whose figures depend on them."""
    return f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}, {os.cpu_count()} CPUs"


def pin_to_one_core() -> str:
    """Pin this process to one CPU for the rest of its life; says which."""
    if hasattr(os, "sched_setaffinity"):
        core = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {core})
        return f"pinned to core {core}"
    return "not pinned (no sched_setaffinity here)"


def run_script(main: Callable[[], int | None]) -> None:
    """Run a benchmark's main() as a script: its exit status, and the cleanup of its servers and
    temporary files on SIGTERM and Ctrl-C too."""
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    with contextlib.suppress(KeyboardInterrupt):
        sys.exit(main())


def checks_line(failures: list[str], what: str) -> str:
    """The last lines of a benchmark that checks: each failure, then the verdict."""
    lines = [f"  FAILED: {failure}" for failure in failures[:50]]
    verdict = "all passed" if not failures else f"{len(failures)} FAILED"
    return "\n".join([*lines, f"checks: {verdict} ({what})"])


def percentiles_ms(seconds: list[float], points: tuple[float, ...] = (50, 99)) -> dict[str, float]:
    """{"p50": ..., "p99": ...} in milliseconds (NaN without samples)."""
    import numpy as np

    if not seconds:
        return {f"p{point:g}": math.nan for point in points}
    values = np.percentile(np.array(seconds) * 1000, points)
    return {f"p{point:g}": float(value) for point, value in zip(points, values)}


# --------------------------------------------------------------------------- agent files


def thesis_actor(folder: Path, name: str = "thesis_actor.onnx", **driver_options) -> Path:
    """A thesis-size ONNX actor (5 -> 64 -> 64 -> 2); options: league.testing.thesis_driver's."""
    from league.agents import export_onnx
    from league.testing import thesis_driver

    return export_onnx(thesis_driver(**driver_options), folder / name)


def course_files(folder: Path, count: int) -> list[Path]:
    """`count` different working agents, as a course uploads them: every combination of format
    (ONNX, TorchScript), observation (compact 5, lidar 20) and batch (dynamic, fixed to 1) in turn."""
    from league import testing
    from league.agents import export_onnx, export_torchscript

    files = []
    for k in range(count):
        torchscript, obs_dim, fixed = k % 2 == 1, (5, 20)[k // 2 % 2], k // 4 % 2 == 1
        driver = testing.thesis_driver(obs_dim=obs_dim, seed=k, target_speed=0.18 + 0.01 * (k % 10))
        name = f"agent{k:03d}-{'ts' if torchscript else 'onnx'}-{obs_dim}-{'fixed' if fixed else 'dynamic'}"
        if torchscript and fixed:
            files.append(testing.torchscript_fixed_batch(driver, folder / f"{name}.pt", obs_dim))
        elif torchscript:
            files.append(export_torchscript(driver, folder / f"{name}.pt"))
        elif fixed:
            files.append(testing.onnx_fixed_batch(driver, folder / f"{name}.onnx", obs_dim))
        else:
            files.append(export_onnx(driver, folder / f"{name}.onnx", obs_dim))
    return files


def broken_files(folder: Path) -> list[Path]:
    """The broken uploads of a course: wrong input size, wrong output size, NaN actions, a pickle, an empty file."""
    from league import testing

    empty = folder / "empty.onnx"
    empty.write_bytes(b"")
    return [testing.onnx_mlp(folder / "wrong-input.onnx", in_dim=7),
            testing.onnx_mlp(folder / "wrong-output.onnx", out_dim=3),
            testing.onnx_mlp(folder / "nan.onnx", nan=True), testing.pickle_renamed_pt(folder / "pickle.pt"), empty]


def plain_loop(path: Path, seeds: list[int]) -> int:
    """What a student writes: a Gymnasium env and an ONNX Runtime session, one call per step."""
    import gymnasium as gym
    import onnxruntime as ort

    import league  # noqa: F401 (registers the env)

    options = ort.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    env = gym.make("league/MicroRacer-v0")
    completed = 0
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        terminated = truncated = False
        while not (terminated or truncated):
            action = session.run(None, {"obs": obs[None, :]})[0][0]
            obs, reward, terminated, truncated, info = env.step(action)
        completed += info["outcome"] == "finished"
    return completed


@contextlib.contextmanager
def one_core() -> Iterator[int]:
    """Pin this process (and the processes it starts meanwhile) to one CPU; yields that CPU."""
    affinity = os.sched_getaffinity(0)
    cpu = min(affinity)
    os.sched_setaffinity(0, {cpu})
    try:
        yield cpu
    finally:
        os.sched_setaffinity(0, affinity)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@contextlib.contextmanager
def backend(kind: str, folder: Path) -> Iterator[dict[str, str]]:
    """LEAGUE_* settings of a new, empty database (which is also the job queue), removed afterwards.

    "sqlite": the embedded default (an SQLite database in the data directory);
    "postgres": a database of its own on the local PostgreSQL.
    """
    if kind == "sqlite":
        yield {"LEAGUE_DATABASE_URL": f"sqlite:///{folder / 'league.db'}"}
        return
    if kind != "postgres":
        raise ValueError(f"unknown backend {kind!r}")
    import psycopg

    name = f"league_bench_{uuid.uuid4().hex[:10]}"
    with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
    try:
        yield {"LEAGUE_DATABASE_URL": f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"}
    finally:
        with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


@contextlib.contextmanager
def database(kind: str, folder: Path) -> Iterator[str]:
    """The URL of a new, empty database of `kind` (see backend), removed afterwards."""
    with backend(kind, folder) as urls:
        yield urls["LEAGUE_DATABASE_URL"]


def started(worker_log: str) -> bool:
    """A worker's job threads run ("consumer started": a source tree from before the database was the queue)."""
    return "worker started" in worker_log or "consumer started" in worker_log.lower()


class League:
    """`league serve` (API + its worker process, or API only) and `league worker`s on loopback, in
    `folder` (the data directory); `settings` are LEAGUE_* variables. Use it as a context manager
    (or call stop()): every process it started is stopped."""

    def __init__(self, folder: Path, *, embedded: bool, workers: int = 0, settings: dict[str, str] | None = None,
                 root: Path = ROOT, round_track_seed: int | None = None):
        """`root`: the source tree the servers run (another checkout, e.g. to compare with a commit).
        `round_track_seed`: every championship round's track seed, instead of the secret draw: the API
        is started through benchmarks/_fixed_track.py, which replaces the draw in its process only
        (a benchmark's way to race the same track in two trees; the product has no such setting)."""
        self.folder, self.port, self.root = folder, free_port(), root
        self.api_launcher = [] if round_track_seed is None else [str(Path(__file__).with_name("_fixed_track.py")),
                                                                 str(round_track_seed)]
        self.url = f"http://127.0.0.1:{self.port}"
        self.env = {**os.environ, "LEAGUE_DATA_DIR": str(folder), "PYTHONPATH": str(root),
                    "LEAGUE_BASELINES_DIR": str(folder / "baselines"),  # empty: the heuristic driver only
                    # the board as the figures have always measured it: visitors' answers, one cached for all
                    "LEAGUE_BOARD_VISIBILITY": "public", **(settings or {})}
        self.token = self._first_instructor()
        self.workers: list[subprocess.Popen] = []  # running (started and not stopped yet)
        self.workers_started = 0
        self.serve = ["serve", "--port", str(self.port)] + ([] if embedded else ["--no-worker"])
        self.api = self._spawn(*self.serve, log="api.log", launcher=self.api_launcher)
        try:
            for _ in range(workers):
                self.start_worker()
            self._wait_healthy()
        except BaseException:
            self.stop()
            raise

    def __enter__(self) -> League:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _first_instructor(self) -> str:
        """A new league and its instructor's token (in a source tree older than `league init`, `users add`
        created the database)."""
        try:
            return self._run("init", "--instructor", "bench").strip()
        except subprocess.CalledProcessError as error:
            if "invalid choice: 'init'" not in error.stderr:
                raise
            return self._run("users", "add", "bench", "--role", "instructor").strip()

    def _run(self, *args: str) -> str:
        return subprocess.run([sys.executable, "-m", "league.server", *args], env=self.env, cwd=self.root, check=True,
                              capture_output=True, text=True, timeout=120).stdout

    def _spawn(self, *args: str, log: str, settings: dict[str, str] | None = None,
               launcher: list[str] | None = None) -> subprocess.Popen:
        """Each process in a session of its own, as services run (systemd starts each so): Linux then
        schedules it as a group of its own, and the benchmark's clients do not share the API's.
        `launcher`: a script and its arguments that run the server's CLI, instead of `-m league.server`."""
        with open(self.folder / log, "ab") as output:
            return subprocess.Popen([sys.executable, *(launcher or ["-m", "league.server"]), *args],
                                    env={**self.env, **(settings or {})}, cwd=self.root, stdout=output,
                                    stderr=subprocess.STDOUT, start_new_session=True)

    def _wait_healthy(self, timeout: float = 60) -> None:
        import httpx

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.api.poll() is not None:
                raise RuntimeError(f"the server exited ({self.api.returncode}):\n{self.log('api.log')}")
            with contextlib.suppress(httpx.HTTPError, ValueError, KeyError):  # "degraded" (503): no worker yet
                if httpx.get(f"{self.url}/api/health", timeout=1).json()["status"] in ("ok", "degraded"):
                    return
            time.sleep(0.1)
        raise RuntimeError(f"the server did not start in {timeout:g} s:\n{self.log('api.log')}")

    def restart_api(self) -> None:
        """Stop `league serve` (SIGTERM, as a deployment restarts it) and start it again on the same port."""
        self.stop_process(self.api)
        self.api = self._spawn(*self.serve, log="api.log", launcher=self.api_launcher)
        self._wait_healthy()

    def start_worker(self, wait: bool = False, timeout: float = 60, cpus: str | None = None,
                     settings: dict[str, str] | None = None) -> subprocess.Popen:
        """A `league worker` process (on the given CPUs, else on all; with more LEAGUE_* `settings`);
        with `wait`, return once its job threads run."""
        log = f"worker-{self.workers_started}.log"  # a log of its own: "worker started" is this one's
        self.workers_started += 1
        worker = self._spawn("worker", *(["--cpus", cpus] if cpus else []), log=log, settings=settings)
        self.workers.append(worker)
        deadline = time.monotonic() + timeout
        while wait and not started(self.log(log)):
            if worker.poll() is not None:
                raise RuntimeError(f"the worker exited ({worker.returncode}):\n{self.log(log)}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"the worker did not start in {timeout:g} s:\n{self.log(log)}")
            time.sleep(0.1)
        return worker

    def log(self, name: str) -> str:
        path = self.folder / name
        return path.read_text(errors="replace")[-4000:] if path.exists() else ""

    @staticmethod
    def stop_process(process: subprocess.Popen, timeout: float = 30) -> None:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()

    def stop_workers(self) -> None:
        while self.workers:
            self.stop_process(self.workers.pop())

    def stop(self) -> None:
        self.stop_workers()
        self.stop_process(self.api)

    def client(self, token: str | None = None, timeout: float = 30):
        import httpx

        token = self.token if token is None else token
        return httpx.Client(base_url=self.url, headers={"Authorization": f"Bearer {token}"} if token else {},
                            timeout=timeout)


def enrol(client, names: list[str]) -> list[str]:
    """Import a roster of students through the API (the instructor's `client`); their tokens, in order."""
    roster = "name\n" + "".join(f"{name}\n" for name in names)
    response = client.post("/api/users/roster", files={"file": ("roster.csv", roster.encode())})
    response.raise_for_status()
    tokens = {row["name"]: row["token"] for row in response.json()["created"]}
    return [tokens[name] for name in names]


def student_names(count: int) -> list[str]:
    return [f"student{k:03d}" for k in range(count)]


def course_settings(*, students: int, uploads: int, episodes: int, seed: int) -> dict[str, str]:
    """LEAGUE_* settings of a course whose students upload `uploads` agents in all, each evaluated
    with `episodes` episodes of `seed`: quotas that let every student send their share at once."""
    per_student = str(math.ceil(uploads / students))
    return {"LEAGUE_EVAL_EPISODES": str(episodes), "LEAGUE_EVAL_SEED": str(seed),
            "LEAGUE_QUOTA_PER_DAY": per_student, "LEAGUE_MAX_JOBS_IN_FLIGHT": per_student}


@contextlib.contextmanager
def course_league(kind: str, prefix: str, workers: int = 2, **settings: str) -> Iterator[tuple[League, Path, str]]:
    """A course's league in a new temporary data directory (with an empty `files/` for the agents to
    upload) on a new database of `kind`: `league serve --no-worker` and `workers` `league worker`s
    with the LEAGUE_* `settings` (CPU slots of their own). Yields the league, the directory and the
    database's URL; stops the servers and removes everything afterwards."""
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp, backend(kind, Path(tmp)) as urls:
        folder = Path(tmp)
        (folder / "files").mkdir()
        settings = {**urls, "LEAGUE_CPU_SLOTS_DIR": str(folder / "cpu-slots"), **settings}
        with League(folder, embedded=False, workers=workers, settings=settings) as league:
            yield league, folder, urls["LEAGUE_DATABASE_URL"]


def queue_is_empty(client) -> bool:
    return not any(client.get("/api/jobs", params={"status": status, "limit": 1}).json()
                   for status in ("queued", "running"))


def wait_queue_empty(league: League, timeout: float) -> float:
    """Poll the instructor's job list until nothing is queued or running (across API restarts);
    returns when it was first seen empty (time.perf_counter)."""
    import httpx

    deadline = Deadline(timeout, "the queue to empty")
    with league.client() as client:
        while True:
            try:
                if queue_is_empty(client):
                    return time.perf_counter()
            except httpx.HTTPError as error:
                deadline.check(error)
            deadline.check("jobs still queued or running")
            time.sleep(0.25)


class Deadline:
    def __init__(self, seconds: float, what: str):
        self.end, self.what = time.monotonic() + seconds, what

    def check(self, detail: object = "") -> None:
        if time.monotonic() > self.end:
            raise TimeoutError(f"{self.what}: not done in time; last: {detail}")


def measure_latency(url: str, token: str | None, path: str, rate: float, seconds: float,
                    senders: int = 8, sent: list[float] | None = None) -> list[float]:
    """Open-loop load of GET `path`: request i is due at i/rate, sent by one of `senders` threads
    (so one slow answer delays no other); returns each request's latency in seconds, and appends
    to `sent` when each was sent (seconds from the start), in the same order. Raises if any
    answer was not 200."""
    import httpx

    total, latencies, failures, lock = int(rate * seconds), [], [], threading.Lock()
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    start = time.perf_counter() + 0.2

    def sender(offset: int) -> None:
        with httpx.Client(base_url=url, headers=headers, timeout=10) as client:
            for i in range(offset, total, senders):
                delay = start + i / rate - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                sent_at = time.perf_counter()
                try:
                    status = client.get(path).status_code
                except httpx.HTTPError as error:
                    status = repr(error)
                elapsed = time.perf_counter() - sent_at
                with lock:
                    if status != 200:
                        failures.append(status)
                        continue
                    latencies.append(elapsed)
                    if sent is not None:
                        sent.append(sent_at - start)

    threads = [threading.Thread(target=sender, args=(k,)) for k in range(senders)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    if failures:
        raise RuntimeError(f"{len(failures)} of {total} GET {path} failed, e.g. {failures[:3]}")
    return latencies
