"""A dead worker, as an administrator lives it:

(a) restart: `league serve`'s worker is killed with SIGKILL; a student uploads at once; the time until a
    job runs again (serve restarts its worker after 1 s, the new worker starts and claims the job);
(b) alert: a real Prometheus (Debian's) scrapes a real league with the alert rules it ships
    (deploy/prometheus/alerts.yml); the league's only `league worker` is killed with SIGKILL (no goodbye:
    its row stays), and the time until `LeagueNoWorker` fires is measured through Prometheus' own API.

    python benchmarks/bench_ops.py [--backend sqlite|postgres] [--interval 5] [--only restart|alert]

The alert fires once no worker has beaten for LEAGUE_WORKER_SILENT_AFTER_S (30 s), then `for: 1m`: about
90 s, plus up to one scrape and one rule evaluation (--interval, Prometheus' intervals here).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import httpx

from _league import ROOT, League, backend, enrol, free_port, machine, run_script

ALERTS = ROOT / "deploy" / "prometheus" / "alerts.yml"


@dataclass
class RestartTime:
    backend: str
    job_running_s: float  # from the kill to a job claimed by the new worker


@dataclass
class AlertTimes:
    backend: str
    interval_s: float
    pending_s: float  # from the kill to the alert's `pending` state (the heartbeat is over 60 s old)
    firing_s: float  # from the kill to `firing`


def prometheus_config(folder: Path, target: str, token: str, interval_s: float) -> Path:
    (folder / "token").write_text(token)
    config = {"global": {"scrape_interval": f"{interval_s:g}s", "evaluation_interval": f"{interval_s:g}s"},
              "rule_files": [str(ALERTS)],
              "scrape_configs": [{"job_name": "league", "static_configs": [{"targets": [target]}],
                                  "authorization": {"credentials_file": str(folder / "token")}}]}
    path = folder / "prometheus.yml"
    path.write_text(json.dumps(config))  # YAML is a superset of JSON
    return path


@contextlib.contextmanager
def prometheus(folder: Path, config: Path):
    binary = shutil.which("prometheus")
    if binary is None:
        raise SystemExit("bench_ops: needs Prometheus (apt-get install prometheus)")
    port = free_port()
    with open(folder / "prometheus.log", "ab") as log:
        process = subprocess.Popen([binary, f"--config.file={config}", f"--storage.tsdb.path={folder / 'tsdb'}",
                                    f"--web.listen-address=127.0.0.1:{port}"], stdout=log, stderr=subprocess.STDOUT)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=30)


def alert_state(api: str, name: str) -> str | None:
    with contextlib.suppress(httpx.HTTPError):
        alerts = httpx.get(f"{api}/api/v1/alerts", timeout=5).json()["data"]["alerts"]
        return next((alert["state"] for alert in alerts if alert["labels"]["alertname"] == name), None)
    return None


def heartbeats_seen(api: str) -> bool:
    with contextlib.suppress(httpx.HTTPError):
        query = httpx.get(f"{api}/api/v1/query", params={"query": "league_worker_heartbeat_timestamp_seconds"},
                          timeout=5).json()
        return bool(query["data"]["result"])
    return False


def wait(condition, timeout_s: float, what: str) -> float:
    started = time.monotonic()
    while not condition():
        if time.monotonic() - started > timeout_s:
            raise SystemExit(f"bench_ops: {what} not seen in {timeout_s:g} s")
        time.sleep(0.5)
    return time.monotonic() - started


def serves_worker(api: subprocess.Popen) -> int | None:
    """The pid of `league serve`'s worker (started by its supervising thread: each thread lists its own children)."""
    tasks = Path(f"/proc/{api.pid}/task").iterdir()
    children = [pid for task in tasks for pid in (task / "children").read_text().split()]
    return next((int(pid) for pid in children if b"worker" in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")),
                None)


def measure_restart(kind: str) -> RestartTime:
    from league import testing

    with tempfile.TemporaryDirectory(prefix="bench-restart-") as name:
        folder = Path(name)
        with backend(kind, folder) as urls, \
                League(folder, embedded=True, settings={**urls, "LEAGUE_BOOTSTRAP": "false"}) as league:
            with league.client() as instructor:
                token = enrol(instructor, ["ann"])[0]
            model = testing.onnx_heuristic(folder / "ann.onnx")
            wait(lambda: httpx.get(f"{league.url}/api/health", timeout=5).json()["status"] == "ok", 120,
                 "serve's worker beating")
            first = serves_worker(league.api)
            os.kill(first, signal.SIGKILL)
            killed = time.monotonic()
            with league.client(token) as student:
                uploaded = student.post("/api/submissions", files={"file": ("ann.onnx", model.read_bytes())})
                uploaded.raise_for_status()
            with league.client() as instructor:
                wait(lambda: any(job["started_at"] for job in instructor.get("/api/jobs").json()), 120,
                     "a job claimed after the restart")
            return RestartTime(kind, time.monotonic() - killed)


def measure_alert(kind: str, interval_s: float) -> AlertTimes:
    with tempfile.TemporaryDirectory(prefix="bench-alert-") as name:
        folder = Path(name)
        metrics_token = "bench-alerts-scraper"
        with backend(kind, folder) as urls, \
                League(folder, embedded=False, workers=1,
                       settings={**urls, "LEAGUE_METRICS_TOKEN": metrics_token, "LEAGUE_BOOTSTRAP": "false"}) as league:
            config = prometheus_config(folder, f"127.0.0.1:{league.port}", metrics_token, interval_s)
            with prometheus(folder, config) as api:
                wait(lambda: heartbeats_seen(api), 120, "a worker heartbeat in Prometheus")
                wait(lambda: alert_state(api, "LeagueNoWorker") is None and heartbeats_seen(api), 60, "a quiet start")
                worker = league.workers.pop()
                worker.send_signal(signal.SIGKILL)
                killed = time.monotonic()
                worker.wait()
                wait(lambda: alert_state(api, "LeagueNoWorker") is not None, 300, "LeagueNoWorker pending")
                pending = time.monotonic() - killed
                wait(lambda: alert_state(api, "LeagueNoWorker") == "firing", 300, "LeagueNoWorker firing")
                return AlertTimes(kind, interval_s, pending, time.monotonic() - killed)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite")
    parser.add_argument("--interval", type=float, default=5.0, help="Prometheus' scrape and evaluation interval (s)")
    parser.add_argument("--only", choices=["restart", "alert"], help="one of the two measures")
    args = parser.parse_args(argv)
    print(machine())
    if args.only in (None, "restart"):
        restart = measure_restart(args.backend)
        print(f"(a) {restart.backend}: serve's worker killed (SIGKILL) -> a job runs again after "
              f"{restart.job_running_s:.1f} s (target <= 10 s)")
    if args.only in (None, "alert"):
        times = measure_alert(args.backend, args.interval)
        print(f"(b) {times.backend}: the only worker killed (SIGKILL) -> LeagueNoWorker pending {times.pending_s:.1f} "
              f"s, firing {times.firing_s:.1f} s (rule: no worker alive for 1 min; scrape and evaluation every "
              f"{times.interval_s:g} s)")
    return 0


if __name__ == "__main__":
    run_script(main)
