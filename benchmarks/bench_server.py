"""Benchmark of the league server: a sandboxed evaluation, and status answers under load.

    python benchmarks/bench_server.py [--episodes 100] [--rate 200] [--seconds 10]
    python benchmarks/bench_server.py --status-trees OLD_CHECKOUT .   # (b) of `league serve`, per source tree

(a) a 100-episode evaluation of a thesis-size ONNX actor (5 -> 64 -> 64 -> 2) in a sandbox
    process, sandbox start included, pinned to one core: target <= 15 s;
(b) GET /api/submissions/{id} of an evaluated submission (100 episodes) at 200 requests/s on
    loopback while a worker keeps evaluating another one (re-runs): target p99 <= 50 ms; with
    a `league worker` beside `league serve --no-worker`, then with `league serve` alone (the
    default setup; its worker is its child process). --status-trees runs the latter only, once
    per source tree given (e.g. a checkout of an older commit, then this one);
(c) the same evaluation as (a) as a job of a `league worker` that may use every CPU (as a
    course runs it): the job's run time with the worker's CPU placement (its thread and the
    sandbox on one CPU, the default) and without it (LEAGUE_CPU_PLACEMENT=false).

Everything runs on this machine: a server on 127.0.0.1, a bounded number of requests.
"""
from __future__ import annotations

import argparse
import tempfile
import threading
import time
from pathlib import Path

from _league import League, measure_latency, one_core, thesis_actor

EVALUATION_TARGET_S = 15.0
P99_TARGET_MS = 50.0


def bench_evaluation(model: Path, episodes: int) -> float:
    from league.evaluation import metrics_run
    from league.server.sandbox.agent import SandboxedAgent, SandboxLimits

    with one_core():  # one core, for this process and the sandbox it starts
        start = time.perf_counter()
        with SandboxedAgent(model, "onnx", SandboxLimits()) as agent:
            result = metrics_run(agent, episodes=episodes, seed=0, on_episode=lambda i, e: agent.new_episode())
        seconds = time.perf_counter() - start
        start_local = time.perf_counter()
        metrics_run(model, episodes=episodes, seed=0)
        local = time.perf_counter() - start_local
    steps = sum(e.steps for e in result.episodes)
    verdict = "ok" if seconds <= EVALUATION_TARGET_S else "OVER TARGET"
    print(f"(a) {episodes}-episode evaluation in a sandbox, one core: {seconds:.2f} s "
          f"(target <= {EVALUATION_TARGET_S:g} s: {verdict})")
    print(f"    {steps} steps, {1e6 * seconds / steps:.0f} us per step; the same run without a sandbox: "
          f"{local:.2f} s; completed {result.completed}/{result.episodes_total}")
    return seconds


# --------------------------------------------------------------------------- (b) status latency


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
        with League(Path(tmp), embedded=embedded, workers=0 if embedded else 1, settings={"LEAGUE_EVAL_EPISODES": "100"},
                    **({"root": root} if root else {})) as league:
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
    verdict = "ok" if p99 <= P99_TARGET_MS else "OVER TARGET"
    print(f"(b) GET status, {len(latencies)} requests at {rate:g}/s, evaluations running {where}"
          f"{f' (source tree {root})' if root else ''}:")
    print(f"    p50 {p50:.1f} ms, p95 {p95:.1f} ms, p99 {p99:.1f} ms, max {latencies.max():.1f} ms "
          f"(target p99 <= {P99_TARGET_MS:g} ms: {verdict}); a job was running in "
          f"{100 * np.mean(np.array(busy) > 0):.0f}% of the samples; idle before: p50 "
          f"{np.percentile(idle, 50):.1f} ms, p99 {np.percentile(idle, 99):.1f} ms", flush=True)
    return float(p99)


# --------------------------------------------------------------------------- (c) evaluation job


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
    print(f"(c) {episodes}-episode evaluation job in a `league worker` on every CPU, CPU placement "
          f"{'on (the default)' if placement else 'off'}: {seconds:.2f} s ({job['status']})", flush=True)
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--rate", type=float, default=200.0, help="GET requests per second")
    parser.add_argument("--seconds", type=float, default=10.0, help="length of the GET load")
    parser.add_argument("--only-jobs", action="store_true", help="only (c)")
    parser.add_argument("--status-trees", type=Path, nargs="+", metavar="TREE",
                        help="only (b) with `league serve`, run from each of these source trees in turn")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="league-bench-model-") as folder:
        model = thesis_actor(Path(folder))
        if args.status_trees:
            p99s = [bench_status(model, args.rate, args.seconds, embedded=True, root=tree.resolve())
                    for tree in args.status_trees]
            print("    p99: " + ", ".join(f"{tree}: {p99:.1f} ms" for tree, p99 in zip(args.status_trees, p99s)))
            return
        if not args.only_jobs:
            bench_evaluation(model, args.episodes)
            bench_status(model, args.rate, args.seconds, embedded=False)
            bench_status(model, args.rate, args.seconds, embedded=True)
        placed = bench_evaluation_job(model, args.episodes, placement=True)
        unplaced = bench_evaluation_job(model, args.episodes, placement=False)
        print(f"    CPU placement makes the evaluation job {unplaced / placed:.1f}x faster")


if __name__ == "__main__":
    main()
