"""Benchmark of the league server (issue 5's performance targets).

    python benchmarks/bench_server.py [--episodes 100] [--rate 200] [--seconds 10]

(a) a 100-episode evaluation of a thesis-size ONNX actor (5 -> 64 -> 64 -> 2) in a sandbox
    process, sandbox start included, pinned to one core: target <= 15 s;
(b) GET /api/submissions/{id} at 200 requests/s on loopback while a `league worker` process
    keeps evaluating (re-runs of every submission): target p99 <= 50 ms; then the same with
    the worker embedded in `league serve` (one process, the default setup).

Everything runs on this machine: a server on 127.0.0.1, a bounded number of requests.
"""
from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

EVALUATION_TARGET_S = 15.0
P99_TARGET_MS = 50.0


def thesis_actor(folder: Path) -> Path:
    from league.agents import export_onnx
    from tests.toolkit_models import thesis_driver

    return export_onnx(thesis_driver(), folder / "thesis_actor.onnx")


def bench_evaluation(model: Path, episodes: int) -> float:
    from league.evaluation import metrics_run
    from league.server.sandbox import SandboxedAgent, SandboxLimits

    affinity = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(affinity)})  # one core, for this process and the sandbox it starts
    try:
        start = time.perf_counter()
        with SandboxedAgent(model, "onnx", SandboxLimits()) as agent:
            result = metrics_run(agent, episodes=episodes, seed=0, on_episode=lambda i, e: agent.new_episode())
        seconds = time.perf_counter() - start
        start_local = time.perf_counter()
        metrics_run(model, episodes=episodes, seed=0)
        local = time.perf_counter() - start_local
    finally:
        os.sched_setaffinity(0, affinity)
    steps = sum(e.steps for e in result.episodes)
    verdict = "ok" if seconds <= EVALUATION_TARGET_S else "OVER TARGET"
    print(f"(a) {episodes}-episode evaluation in a sandbox, one core: {seconds:.2f} s "
          f"(target <= {EVALUATION_TARGET_S:g} s: {verdict})")
    print(f"    {steps} steps, {1e6 * seconds / steps:.0f} us per step; the same run without a sandbox: "
          f"{local:.2f} s; completed {result.completed}/{result.episodes_total}")
    return seconds


# --------------------------------------------------------------------------- (b) status latency


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class League:
    """`league serve` (+ `league worker`) on loopback, in a temporary data directory."""

    def __init__(self, folder: Path, embedded: bool):
        self.folder, self.port = folder, free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.env = {**os.environ, "LEAGUE_DATA_DIR": str(folder), "PYTHONPATH": str(ROOT),
                    "LEAGUE_EVAL_EPISODES": "20"}
        self.token = self._run("users", "add", "bench", "--role", "instructor").strip()
        serve = ["serve", "--port", str(self.port)] + ([] if embedded else ["--no-worker"])
        self.processes = [self._spawn(*serve, log="api.log")]
        if not embedded:
            self.processes.append(self._spawn("worker", log="worker.log"))
        self._wait_healthy()

    def _run(self, *args: str) -> str:
        return subprocess.run([sys.executable, "-m", "league.server", *args], env=self.env, check=True,
                              capture_output=True, text=True).stdout

    def _spawn(self, *args: str, log: str) -> subprocess.Popen:
        return subprocess.Popen([sys.executable, "-m", "league.server", *args], env=self.env,
                                stdout=open(self.folder / log, "wb"), stderr=subprocess.STDOUT)

    def _wait_healthy(self) -> None:
        import httpx

        for _ in range(300):
            try:
                if httpx.get(f"{self.url}/api/health", timeout=1).status_code == 200:
                    return
            except httpx.HTTPError:
                time.sleep(0.1)
        raise RuntimeError("the server did not start")

    def stop(self) -> None:
        for process in self.processes:
            process.terminate()
        for process in self.processes:
            process.wait(timeout=30)


def keep_evaluating(client, stop: threading.Event, busy: list[int]) -> None:
    """Re-run every evaluation whenever the queue runs dry, and count the jobs that ran."""
    while not stop.is_set():
        running = client.get("/api/jobs", params={"status": "running"}).json()
        queued = client.get("/api/jobs", params={"status": "queued"}).json()
        busy.append(len(running))
        if not running and not queued:
            client.post("/api/evaluations/rerun", json={"all": True})
        stop.wait(0.5)


def measure_status_latency(url: str, token: str, submission_id: int, rate: float, seconds: float) -> list[float]:
    """Open-loop load: request i is due at i/rate; 8 sender threads so one slow answer delays no other."""
    import httpx

    total, latencies, lock = int(rate * seconds), [], threading.Lock()
    start = time.perf_counter() + 0.2

    def sender(offset: int, threads: int) -> None:
        with httpx.Client(base_url=url, headers={"Authorization": f"Bearer {token}"}, timeout=10) as client:
            for i in range(offset, total, threads):
                delay = start + i / rate - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                sent = time.perf_counter()
                response = client.get(f"/api/submissions/{submission_id}")
                elapsed = time.perf_counter() - sent
                assert response.status_code == 200
                with lock:
                    latencies.append(elapsed)

    threads = [threading.Thread(target=sender, args=(k, 8)) for k in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return latencies


def bench_status(model: Path, rate: float, seconds: float, embedded: bool) -> float:
    import httpx
    import numpy as np

    with tempfile.TemporaryDirectory(prefix="league-bench-") as tmp:
        league = League(Path(tmp), embedded)
        try:
            client = httpx.Client(base_url=league.url, headers={"Authorization": f"Bearer {league.token}"}, timeout=30)
            with open(model, "rb") as handle:
                submission_id = client.post("/api/submissions", files={"file": (model.name, handle)}).json()["id"]
            stop, busy = threading.Event(), []
            loader = threading.Thread(target=keep_evaluating, args=(client, stop, busy))
            loader.start()
            time.sleep(2)  # evaluations under way
            latencies = np.array(measure_status_latency(league.url, league.token, submission_id, rate, seconds)) * 1000
            stop.set()
            loader.join()
        finally:
            league.stop()
    p50, p95, p99 = np.percentile(latencies, [50, 95, 99])
    where = "embedded in `league serve`" if embedded else "in a `league worker` process"
    verdict = "ok" if p99 <= P99_TARGET_MS else "OVER TARGET"
    print(f"(b) GET status, {len(latencies)} requests at {rate:g}/s, evaluations running {where}:")
    print(f"    p50 {p50:.1f} ms, p95 {p95:.1f} ms, p99 {p99:.1f} ms, max {latencies.max():.1f} ms "
          f"(target p99 <= {P99_TARGET_MS:g} ms: {verdict}); a job was running in "
          f"{100 * np.mean(np.array(busy) > 0):.0f}% of the samples")
    return float(p99)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--rate", type=float, default=200.0, help="GET requests per second")
    parser.add_argument("--seconds", type=float, default=10.0, help="length of the GET load")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="league-bench-model-") as folder:
        model = thesis_actor(Path(folder))
        bench_evaluation(model, args.episodes)
        bench_status(model, args.rate, args.seconds, embedded=False)
        bench_status(model, args.rate, args.seconds, embedded=True)


if __name__ == "__main__":
    main()
