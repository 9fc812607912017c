"""Benchmark of the league server: sandboxed evaluations, and status answers under load.

    python benchmarks/bench_server.py [--episodes 100] [--uploads 20] [--rate 200] [--seconds 10]
    python benchmarks/bench_server.py --status-trees OLD_CHECKOUT .   # (d) of `league serve`, per source tree
    python benchmarks/bench_server.py --torchscript-trees OLD_CHECKOUT . [--settle 20]   # (f), per source tree

(a) 100 episodes of a thesis-size ONNX actor (5 -> 64 -> 64 -> 2), one core, three ways: the
    plain per-episode loop a student writes (no sandbox), lockstep metrics_run without a sandbox,
    and in a sandbox process (start included): targets <= 15 s, the sandbox <= 1.5x the
    unsandboxed lockstep run (issue 12);
(b) from upload to figures, a `league worker` on one CPU: target >= 1x the plain loop of (a);
(c) 20 uploads at once to that worker (validation and evaluation each): target >= 100
    evaluations per core-minute;
(d) GET /api/submissions/{id} of an evaluated submission (100 episodes) at 200 requests/s on
    loopback while a worker keeps evaluating another one (re-runs): target p99 <= 50 ms; with
    a `league worker` beside `league serve --no-worker`, then with `league serve` alone (the
    default setup; its worker is its child process). --status-trees runs the latter only, once
    per source tree given (e.g. a checkout of an older commit, then this one);
(e) the same evaluation as (a) as a job of a `league worker` that may use every CPU (as a
    course runs it): the job's run time with the worker's CPU placement (its thread and the
    sandbox on one CPU, the default) and without it (LEAGUE_CPU_PLACEMENT=false);
(f) TorchScript uploads to a new `league worker` (one job thread), one after the other, the first
    `--settle` seconds after it started: upload to ready (validated) and to evaluated, the first
    beside the later ones, and its fork server's memory. --torchscript-trees runs only (f), once
    per source tree given (e.g. a checkout of an older commit, then this one).

Everything runs on this machine: a server on 127.0.0.1, a bounded number of requests.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import threading
import time
from pathlib import Path

from _league import ROOT, League, measure_latency, one_core, plain_loop, thesis_actor

EVALUATION_TARGET_S = 15.0
SANDBOX_COST_TARGET = 1.5  # sandboxed lockstep run against the unsandboxed one
RATE_TARGET = 100  # evaluations per core-minute
P99_TARGET_MS = 50.0


def bench_evaluation(model: Path, episodes: int) -> float:
    """(a): returns the plain loop's seconds, the reference of (b)."""
    from league.evaluation import episode_seeds, metrics_run
    from league.track import set_track_cache_size
    from league.server.sandbox.agent import SandboxedAgent
    from league.validation.limits import SandboxLimits

    def sandboxed():
        with SandboxedAgent(model, "onnx", SandboxLimits()) as agent:
            return metrics_run(agent, episodes=episodes, seed=0)

    with one_core():  # one core, for this process and the sandbox it starts: wall time is their CPU time
        plain = wall_time(lambda: plain_loop(model, episode_seeds(0, episodes)))
        set_track_cache_size(max(128, episodes))  # empty: each lockstep run draws its tracks, as the plain loop
        local = wall_time(lambda: metrics_run(model, episodes=episodes, seed=0))
        first = wall_time(lambda: SandboxedAgent(model, "onnx", SandboxLimits()).close())  # once per worker thread
        set_track_cache_size(max(128, episodes))
        start = time.perf_counter()
        result = sandboxed()
        seconds = time.perf_counter() - start
    print(f"(a) {episodes} episodes of a thesis-size ONNX actor, one core, every track drawn "
          f"(a worker thread's first sandbox, started before: {first:.2f} s, its fork server and isolation probe):")
    print(f"    plain loop (gym.make + ONNX Runtime, one call per step):   {plain:6.2f} s")
    print(f"    metrics_run in lockstep, no sandbox:                        {local:6.2f} s")
    print(f"    metrics_run in lockstep, in a sandbox (start included):     {seconds:6.2f} s  "
          f"(target <= {EVALUATION_TARGET_S:g} s: {verdict(seconds <= EVALUATION_TARGET_S)})")
    print(f"    the sandbox costs {seconds / local:.2f}x the unsandboxed lockstep run "
          f"(target <= {SANDBOX_COST_TARGET:g}x: {verdict(seconds / local <= SANDBOX_COST_TARGET)}); "
          f"the sandboxed run is {plain / seconds:.1f}x the plain loop; completed {result.completed}/{episodes}")
    return plain


def wall_time(work) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def verdict(ok: bool) -> str:
    return "ok" if ok else "OVER TARGET"


# --------------------------------------------------------------------------- (b), (c) a worker on one CPU


def bench_worker_on_one_cpu(model: Path, episodes: int, plain: float, uploads: int) -> None:
    """(b) one upload to its figures; (c) `uploads` uploads at once, evaluations per core-minute."""
    cpu = str(max(os.sched_getaffinity(0)))
    with tempfile.TemporaryDirectory(prefix="league-bench-") as tmp:
        settings = {"LEAGUE_EVAL_EPISODES": str(episodes), "LEAGUE_WORKER_THREADS": "1"}
        with League(Path(tmp), embedded=False, settings=settings) as league:
            league.start_worker(wait=True, cpus=cpu)
            client = league.client()
            first = wall_time(lambda: wait_evaluated(client, [upload_file(client, model)]))  # starts its fork servers
            second = wall_time(lambda: wait_evaluated(client, [upload_file(client, model)]))
            print(f"(b) upload to figures, {episodes} episodes, a `league worker` on CPU {cpu}: {second:.2f} s, "
                  f"{plain / second:.2f}x the plain loop of (a) (target >= 1x: {verdict(plain / second >= 1)}); "
                  f"the first upload a new worker sees: {first:.2f} s")
            seconds = wall_time(lambda: wait_evaluated(client, [upload_file(client, model) for _ in range(uploads)]))
    rate = 60 * uploads / seconds
    print(f"(c) {uploads} uploads at once, validated and evaluated ({episodes} episodes) by that worker: "
          f"{seconds:.1f} s, {rate:.0f} evaluations per core-minute "
          f"(target >= {RATE_TARGET}: {verdict(rate >= RATE_TARGET)})")


def upload_file(client, model: Path) -> int:
    with open(model, "rb") as handle:
        response = client.post("/api/submissions", files={"file": (model.name, handle)})
    response.raise_for_status()
    return response.json()["id"]


def wait_evaluated(client, submission_ids: list[int], timeout: float = 600) -> None:
    deadline = time.monotonic() + timeout
    for submission_id in submission_ids:
        while (status := evaluation_status(client, submission_id)) not in ("done", "failed", "rejected"):
            if time.monotonic() > deadline:
                raise TimeoutError(f"submission {submission_id}: still {status}")
            time.sleep(0.05)
        if status != "done":
            raise RuntimeError(f"submission {submission_id}: {status}")


def evaluation_status(client, submission_id: int) -> str:
    """The evaluation's status once the upload is validated (ready), else the submission's."""
    answer = client.get(f"/api/submissions/{submission_id}").json()
    return (answer["evaluation"] or {}).get("status", "queued") if answer["status"] == "ready" else answer["status"]


# --------------------------------------------------------------------------- (d) status latency


def keep_evaluating(client, stop: threading.Event, busy: list[int], submission_id: int) -> None:
    """Keep one re-run of a submission's evaluation waiting behind the running one, and count the jobs
    that ran."""
    while not stop.is_set():
        running = client.get("/api/jobs", params={"status": "running"}).json()
        queued = client.get("/api/jobs", params={"status": "queued"}).json()
        busy.append(len(running))
        if not queued:
            client.post("/api/evaluations/rerun", json={"submission_id": submission_id})
        stop.wait(0.5)


def evaluated(client, model: Path, timeout: float = 300) -> int:
    """Upload `model`; its id once its evaluation is done."""
    with open(model, "rb") as handle:
        submission_id = client.post("/api/submissions", files={"file": (model.name, handle)}).json()["id"]
    deadline = time.monotonic() + timeout
    while (client.get(f"/api/submissions/{submission_id}").json().get("evaluation") or {}).get("status") != "done":
        if time.monotonic() > deadline:
            raise TimeoutError(f"submission {submission_id} was not evaluated in {timeout:g} s")
        time.sleep(0.5)
    return submission_id


def bench_status(model: Path, rate: float, seconds: float, embedded: bool, root: Path | None = None) -> float:
    import numpy as np

    with tempfile.TemporaryDirectory(prefix="league-bench-") as tmp:
        with League(Path(tmp), embedded=embedded, workers=0 if embedded else 1,
                    settings={"LEAGUE_EVAL_EPISODES": "100"}, **({"root": root} if root else {})) as league:
            client = league.client()
            polled, evaluating = evaluated(client, model), evaluated(client, model)
            path = f"/api/submissions/{polled}"
            idle = np.array(measure_latency(league.url, league.token, path, rate, seconds)) * 1000
            stop, busy = threading.Event(), []
            loader = threading.Thread(target=keep_evaluating, args=(client, stop, busy, evaluating))
            loader.start()
            time.sleep(2)  # evaluations under way
            try:
                latencies = np.array(measure_latency(league.url, league.token, path, rate, seconds)) * 1000
            finally:
                stop.set()
                loader.join()
    p50, p95, p99 = np.percentile(latencies, [50, 95, 99])
    where = "by `league serve`" if embedded else "in a `league worker` process"
    print(f"(d) GET status, {len(latencies)} requests at {rate:g}/s, evaluations running {where}"
          f"{f' (source tree {root})' if root else ''}:")
    print(f"    p50 {p50:.1f} ms, p95 {p95:.1f} ms, p99 {p99:.1f} ms, max {latencies.max():.1f} ms "
          f"(target p99 <= {P99_TARGET_MS:g} ms: {verdict(p99 <= P99_TARGET_MS)}); a job was running in "
          f"{100 * np.mean(np.array(busy) > 0):.0f}% of the samples; idle before: p50 "
          f"{np.percentile(idle, 50):.1f} ms, p99 {np.percentile(idle, 99):.1f} ms", flush=True)
    return float(p99)


# --------------------------------------------------------------------------- (e) evaluation job


def bench_evaluation_job(model: Path, episodes: int, placement: bool) -> float:
    from datetime import datetime

    with tempfile.TemporaryDirectory(prefix="league-bench-") as tmp:
        with League(Path(tmp), embedded=False, settings={"LEAGUE_EVAL_EPISODES": str(episodes)}) as league:
            league.start_worker(wait=True, settings={"LEAGUE_CPU_PLACEMENT": str(placement).lower(),
                                                     "LEAGUE_CPU_SLOTS_DIR": str(Path(tmp) / "cpu-slots")})
            client = league.client()
            with open(model, "rb") as handle:
                client.post("/api/submissions", files={"file": (model.name, handle)}).raise_for_status()
            deadline = time.monotonic() + 60 + episodes
            while True:
                jobs = client.get("/api/jobs", params={"limit": 100}).json()
                evaluation = [job for job in jobs if job["kind"] == "evaluate" and job["status"] in ("done", "failed")]
                if evaluation:
                    break
                if time.monotonic() > deadline:
                    raise TimeoutError(f"the evaluation did not finish: {jobs}")
                time.sleep(0.2)
    job = evaluation[0]
    seconds = (datetime.fromisoformat(job["finished_at"]) - datetime.fromisoformat(job["started_at"])).total_seconds()
    print(f"(e) {episodes}-episode evaluation job in a `league worker` on every CPU, CPU placement "
          f"{'on (the default)' if placement else 'off'}: {seconds:.2f} s ({job['status']})", flush=True)
    return seconds


# --------------------------------------------------------------------------- (f) first TorchScript upload


def bench_first_torchscript(model: Path, episodes: int, settle_s: float, uploads: int = 3,
                            root: Path = ROOT) -> list[tuple[float, float]]:
    """(f): (seconds to ready, seconds to evaluated) of each upload, in order."""
    times = []
    with tempfile.TemporaryDirectory(prefix="league-bench-") as tmp:
        settings = {"LEAGUE_EVAL_EPISODES": str(episodes), "LEAGUE_WORKER_THREADS": "1"}
        with League(Path(tmp), embedded=False, settings=settings, root=root) as league:
            worker = league.start_worker(wait=True)
            time.sleep(settle_s)  # the students' first upload comes a while after the start
            client = league.client()
            for _ in range(uploads):
                start = time.perf_counter()
                submission_id = upload_file(client, model)
                while evaluation_status(client, submission_id) in ("pending", "validating"):
                    time.sleep(0.02)
                ready = time.perf_counter() - start
                wait_evaluated(client, [submission_id])
                times.append((ready, time.perf_counter() - start))
            memory = ", ".join(f"{fork_server_rss_mb(pid):.0f} MB" for pid in fork_servers(worker.pid))
    first, later = times[0], times[1:]
    print(f"(f) TorchScript uploads to a new `league worker`, the first {settle_s:g} s after its start"
          f"{f' (source tree {root})' if root != ROOT else ''}: to ready {first[0]:.2f} s, to evaluated "
          f"{first[1]:.2f} s; later ones: to ready {sum(t[0] for t in later) / len(later):.2f} s, to evaluated "
          f"{sum(t[1] for t in later) / len(later):.2f} s; its fork server's resident memory: {memory}", flush=True)
    return times


def fork_servers(worker: int) -> list[int]:
    """The worker's fork servers (children of its job threads: /proc/PID/task/TID/children each)."""
    children = [pid for task in Path(f"/proc/{worker}/task").iterdir()
                for pid in (task / "children").read_text().split()]
    return [int(pid) for pid in children if b"--fork-server" in Path(f"/proc/{pid}/cmdline").read_bytes()]


def fork_server_rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--rate", type=float, default=200.0, help="GET requests per second")
    parser.add_argument("--seconds", type=float, default=10.0, help="length of the GET load")
    parser.add_argument("--uploads", type=int, default=20, help="uploads at once in (c)")
    parser.add_argument("--only-jobs", action="store_true", help="only (e)")
    parser.add_argument("--status-trees", type=Path, nargs="+", metavar="TREE",
                        help="only (d) with `league serve`, run from each of these source trees in turn")
    parser.add_argument("--torchscript-trees", type=Path, nargs="+", metavar="TREE",
                        help="only (f), run from each of these source trees in turn")
    parser.add_argument("--settle", type=float, default=20.0, help="seconds from a worker's start to the first "
                                                                   "upload in (f)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="league-bench-model-") as folder:
        model = thesis_actor(Path(folder))
        scripted = thesis_torchscript(Path(folder))
        if args.torchscript_trees:
            for tree in args.torchscript_trees:
                bench_first_torchscript(scripted, args.episodes, args.settle, root=tree.resolve())
            return
        if args.status_trees:
            p99s = [bench_status(model, args.rate, args.seconds, embedded=True, root=tree.resolve())
                    for tree in args.status_trees]
            print("    p99: " + ", ".join(f"{tree}: {p99:.1f} ms" for tree, p99 in zip(args.status_trees, p99s)))
            return
        if not args.only_jobs:
            plain = bench_evaluation(model, args.episodes)
            bench_worker_on_one_cpu(model, args.episodes, plain, args.uploads)
            bench_status(model, args.rate, args.seconds, embedded=False)
            bench_status(model, args.rate, args.seconds, embedded=True)
        placed = bench_evaluation_job(model, args.episodes, placement=True)
        unplaced = bench_evaluation_job(model, args.episodes, placement=False)
        print(f"    CPU placement makes the evaluation job {unplaced / placed:.1f}x faster")
        if not args.only_jobs:
            bench_first_torchscript(scripted, args.episodes, args.settle)


def thesis_torchscript(folder: Path) -> Path:
    """The thesis-size actor of (a), scripted (torch.jit.script) as a student exports it."""
    from league.agents import export_torchscript
    from tests.toolkit_models import thesis_driver

    return export_torchscript(thesis_driver(), folder / "thesis_actor.pt")


if __name__ == "__main__":
    main()
