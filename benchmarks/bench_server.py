"""Benchmark of the league server: sandboxed evaluations, and status answers under load.

    python benchmarks/bench_server.py [--episodes 100] [--uploads 20] [--rate 200] [--seconds 10] [--parts a b c d e f]
    python benchmarks/bench_server.py --status-trees OLD_CHECKOUT .   # (d) of `league serve`, per source tree
    python benchmarks/bench_server.py --torchscript-trees OLD_CHECKOUT . [--settle 20]   # (f), per source tree

(a) 100 episodes of a thesis-size ONNX actor (5 -> 64 -> 64 -> 2), one core, three ways: the
    plain per-episode loop a student writes (no sandbox), lockstep metrics_run without a sandbox,
    and in a sandbox process (start included), each lockstep run again with its tracks cached:
    targets <= 15 s, the sandbox <= 1.5x the unsandboxed lockstep run (issue 12); and a sandbox's
    start once its thread's fork servers run (an older tree's: this script copied into its checkout);
(b) from upload to figures, a `league worker` on one CPU: target >= 1x the plain loop of (a);
(c) 20 uploads at once to that worker (validation and evaluation each), once its fork servers have
    prepared their runtimes (the steady state; once per worker start): target >= 300
    evaluations per core-minute (issue 33), beside the ceilings (a)'s cached runs set and the same
    uploads to a worker that keeps no tracks (LEAGUE_TRACK_CACHE_SIZE=0: every evaluation draws its
    100 tracks again);
(d) GET /api/submissions/{id} of an evaluated submission (100 episodes) at 200 requests/s on
    loopback while a worker keeps evaluating another one (re-runs): target p99 <= 50 ms, and the API
    process's CPU time per answer under that load (/proc: steadier than latencies on a busy machine); with
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
import statistics
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from _league import ROOT, League, measure_latency, one_core, plain_loop, thesis_actor

EVALUATION_TARGET_S = 15.0
SANDBOX_COST_TARGET = 1.5  # sandboxed lockstep run against the unsandboxed one
RATE_TARGET = 300  # evaluations per core-minute (issue 33)
P99_TARGET_MS = 50.0
SANDBOX_STARTS = 20


@dataclass
class Evaluation:
    """(a) wall seconds on one core."""

    episodes: int
    first_sandbox_s: float  # a worker thread's first sandbox: its fork server and isolation probe
    sandbox_start_s: float  # the median start of the later ones (fork, confinement, model load)
    plain_s: float
    lockstep_s: float  # metrics_run, no sandbox
    cached_lockstep_s: float  # the same again, its tracks cached: the floor of an evaluation's CPU
    sandboxed_s: float  # metrics_run in a sandbox, its start included
    cached_sandboxed_s: float  # the same again, its tracks cached: the floor of an evaluation the server runs
    completed: int


@dataclass
class WorkerOnOneCpu:
    """(b), (c): a `league worker` on one CPU."""

    cpu: str
    episodes: int
    first_upload_s: float  # upload to figures, the first upload the worker sees
    upload_s: float  # the next one
    uploads: int  # at once, in (c)
    uploads_s: float
    unshared_uploads_s: float | None = None  # (c) again, by a worker that keeps no tracks

    @property
    def per_core_minute(self) -> float:
        return 60 * self.uploads / self.uploads_s


@dataclass
class Status:
    """(d) latencies of GET /api/submissions/{id}, in milliseconds."""

    embedded: bool  # the worker is `league serve`'s child (else a `league worker` process)
    root: Path | None  # the source tree, when not this one
    rate: float
    ms: dict[str, float]  # p50, p95, p99, max, under load
    requests: int
    busy_share: float  # the share of samples in which a job was running
    idle_ms: dict[str, float]  # p50, p99 before the load
    cpu_ms: float = float("nan")  # CPU time of the API process per answer under load (its own: not its worker's)


@dataclass
class EvaluationJob:
    """(e) an evaluation job's run time, as the server recorded it."""

    episodes: int
    placement: bool
    seconds: float
    status: str


@dataclass
class FirstTorchScript:
    """(f) TorchScript uploads to a new worker, in order: seconds to ready and to evaluated."""

    settle_s: float
    root: Path
    times: list[tuple[float, float]]
    fork_server_mb: list[float]


def bench_evaluation(model: Path, episodes: int) -> Evaluation:
    """(a): its plain loop's seconds are the reference of (b)."""
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
        cached = wall_time(lambda: metrics_run(model, episodes=episodes, seed=0))  # (the tracks of `local`)
        first = wall_time(lambda: SandboxedAgent(model, "onnx", SandboxLimits()).close())  # once per worker thread
        later_start = statistics.median(sandbox_start(model) for _ in range(SANDBOX_STARTS))
        set_track_cache_size(max(128, episodes))
        start = time.perf_counter()
        result = sandboxed()
        seconds = time.perf_counter() - start
        cached_sandboxed = wall_time(sandboxed)
    return Evaluation(episodes=episodes, first_sandbox_s=first, sandbox_start_s=later_start, plain_s=plain,
                      lockstep_s=local, cached_lockstep_s=cached, sandboxed_s=seconds,
                      cached_sandboxed_s=cached_sandboxed, completed=result.completed)


def sandbox_start(model: Path) -> float:
    """Seconds to a sandbox that is ready (forked, confined, its model loaded), its fork server running."""
    from league.server.sandbox.agent import SandboxedAgent
    from league.validation.limits import SandboxLimits

    start = time.perf_counter()
    agent = SandboxedAgent(model, "onnx", SandboxLimits())
    seconds = time.perf_counter() - start
    agent.close()
    return seconds


def report_evaluation(f: Evaluation) -> None:
    print(f"(a) {f.episodes} episodes of a thesis-size ONNX actor, one core, every track drawn (a worker thread's "
          f"first sandbox, started before: {f.first_sandbox_s:.2f} s, its fork server and isolation probe; each "
          f"later one: {1000 * f.sandbox_start_s:.1f} ms, the median of {SANDBOX_STARTS} starts):")
    print(f"    plain loop (gym.make + ONNX Runtime, one call per step):   {f.plain_s:6.2f} s")
    print(f"    metrics_run in lockstep, no sandbox:                        {f.lockstep_s:6.2f} s")
    print(f"    the same again, its tracks cached (no sandbox, no validation): {f.cached_lockstep_s:6.2f} s")
    print(f"    metrics_run in lockstep, in a sandbox (start included):     {f.sandboxed_s:6.2f} s  "
          f"(target <= {EVALUATION_TARGET_S:g} s: {verdict(f.sandboxed_s <= EVALUATION_TARGET_S)})")
    print(f"    the same again, its tracks cached:                          {f.cached_sandboxed_s:6.2f} s")
    cost = f.sandboxed_s / f.lockstep_s
    print(f"    the sandbox costs {cost:.2f}x the unsandboxed lockstep run "
          f"(target <= {SANDBOX_COST_TARGET:g}x: {verdict(cost <= SANDBOX_COST_TARGET)}); "
          f"the sandboxed run is {f.plain_s / f.sandboxed_s:.1f}x the plain loop; completed "
          f"{f.completed}/{f.episodes}")


def wall_time(work) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def verdict(ok: bool) -> str:
    return "ok" if ok else "OVER TARGET"


# --------------------------------------------------------------------------- (b), (c) a worker on one CPU


def bench_worker_on_one_cpu(model: Path, episodes: int, uploads: int) -> WorkerOnOneCpu:
    """(b) one upload to its figures; (c) `uploads` uploads at once, evaluations per core-minute."""
    cpu = str(max(os.sched_getaffinity(0)))
    with tempfile.TemporaryDirectory(prefix="league-bench-") as tmp:
        settings = {"LEAGUE_EVAL_EPISODES": str(episodes), "LEAGUE_WORKER_THREADS": "1"}
        with League(Path(tmp), embedded=False, settings=settings) as league:
            league.start_worker(wait=True, cpus=cpu)
            client = league.client()
            worker = league.workers[-1].pid
            first = wall_time(lambda: wait_evaluated(client, [upload_file(client, model)]))  # starts its fork servers
            second = wall_time(lambda: wait_evaluated(client, [upload_file(client, model)]))
            settle(worker)
            seconds = wall_time(lambda: wait_evaluated(client, [upload_file(client, model) for _ in range(uploads)]))
            unshared = uploads_without_shared_tracks(league, client, model, uploads, cpu)
    return WorkerOnOneCpu(cpu=cpu, episodes=episodes, first_upload_s=first, upload_s=second, uploads=uploads,
                          uploads_s=seconds, unshared_uploads_s=unshared)


def uploads_without_shared_tracks(league: League, client, model: Path, uploads: int, cpu: str) -> float:
    """(c) by a new worker on the same CPU that keeps no tracks (its cache off), once it has seen an upload."""
    league.stop_workers()
    worker = league.start_worker(wait=True, cpus=cpu, settings={"LEAGUE_TRACK_CACHE_SIZE": "0"}).pid
    wait_evaluated(client, [upload_file(client, model)])  # its fork servers
    settle(worker)
    return wall_time(lambda: wait_evaluated(client, [upload_file(client, model) for _ in range(uploads)]))


def report_worker(f: WorkerOnOneCpu, plain_s: float, cached_lockstep_s: float, cached_sandboxed_s: float) -> None:
    print(f"(b) upload to figures, {f.episodes} episodes, a `league worker` on CPU {f.cpu}: {f.upload_s:.2f} s, "
          f"{plain_s / f.upload_s:.2f}x the plain loop of (a) (target >= 1x: {verdict(plain_s / f.upload_s >= 1)}); "
          f"the first upload a new worker sees: {f.first_upload_s:.2f} s")
    rate = f.per_core_minute
    print(f"(c) {f.uploads} uploads at once, validated and evaluated ({f.episodes} episodes) by that worker: "
          f"{f.uploads_s:.1f} s, {rate:.0f} evaluations per core-minute "
          f"(target >= {RATE_TARGET}: {verdict(rate >= RATE_TARGET)})")
    print(f"    the ceiling of an evaluation that were only (a)'s lockstep run with its tracks cached (no sandbox, "
          f"no validation, no database): {60 / cached_lockstep_s:.0f} per core-minute")
    print(f"    the ceiling of an evaluation that were only (a)'s sandboxed run with its tracks cached (the part no "
          f"evaluation skips; no validation, no database): {60 / cached_sandboxed_s:.0f} per core-minute")
    if f.unshared_uploads_s is not None:
        before = 60 * f.uploads / f.unshared_uploads_s
        print(f"    the same by a worker that keeps no tracks (each evaluation draws its own): "
              f"{f.unshared_uploads_s:.1f} s, {before:.0f} per core-minute; shared tracks: {rate / before:.2f}x")


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


def bench_status(model: Path, rate: float, seconds: float, embedded: bool, root: Path | None = None) -> Status:
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
                used = cpu_seconds(league.api.pid)  # robust on a busy machine, unlike the latencies
                latencies = np.array(measure_latency(league.url, league.token, path, rate, seconds)) * 1000
                used = cpu_seconds(league.api.pid) - used
            finally:
                stop.set()
                loader.join()
    p50, p95, p99 = np.percentile(latencies, [50, 95, 99])
    return Status(embedded=embedded, root=root, rate=rate,
                  ms={"p50": float(p50), "p95": float(p95), "p99": float(p99), "max": float(latencies.max())},
                  requests=len(latencies), busy_share=float(np.mean(np.array(busy) > 0)),
                  idle_ms={"p50": float(np.percentile(idle, 50)), "p99": float(np.percentile(idle, 99))},
                  cpu_ms=1000 * used / len(latencies))


def report_status(f: Status) -> None:
    where = "by `league serve`" if f.embedded else "in a `league worker` process"
    print(f"(d) GET status, {f.requests} requests at {f.rate:g}/s, evaluations running {where}"
          f"{f' (source tree {f.root})' if f.root else ''}:")
    print(f"    p50 {f.ms['p50']:.1f} ms, p95 {f.ms['p95']:.1f} ms, p99 {f.ms['p99']:.1f} ms, max {f.ms['max']:.1f} ms "
          f"(target p99 <= {P99_TARGET_MS:g} ms: {verdict(f.ms['p99'] <= P99_TARGET_MS)}); a job was running in "
          f"{100 * f.busy_share:.0f}% of the samples; idle before: p50 {f.idle_ms['p50']:.1f} ms, p99 "
          f"{f.idle_ms['p99']:.1f} ms; the API's CPU: {f.cpu_ms:.2f} ms per answer (the loader's few requests and "
          "its heartbeat included)", flush=True)


# --------------------------------------------------------------------------- (e) evaluation job


def bench_evaluation_job(model: Path, episodes: int, placement: bool) -> EvaluationJob:
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
    return EvaluationJob(episodes=episodes, placement=placement, seconds=seconds, status=job["status"])


def report_job(f: EvaluationJob) -> None:
    print(f"(e) {f.episodes}-episode evaluation job in a `league worker` on every CPU, CPU placement "
          f"{'on (the default)' if f.placement else 'off'}: {f.seconds:.2f} s ({f.status})", flush=True)


# --------------------------------------------------------------------------- (f) first TorchScript upload


def bench_first_torchscript(model: Path, episodes: int, settle_s: float, uploads: int = 3,
                            root: Path = ROOT) -> FirstTorchScript:
    """(f): (seconds to ready, seconds to evaluated) of each upload, in order, and the fork server's memory."""
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
            memory = [fork_server_rss_mb(pid) for pid in fork_servers(worker.pid)]
    return FirstTorchScript(settle_s=settle_s, root=root, times=times, fork_server_mb=memory)


def report_torchscript(f: FirstTorchScript) -> None:
    first, later = f.times[0], f.times[1:]
    print(f"(f) TorchScript uploads to a new `league worker`, the first {f.settle_s:g} s after its start"
          f"{f' (source tree {f.root})' if f.root != ROOT else ''}: to ready {first[0]:.2f} s, to evaluated "
          f"{first[1]:.2f} s; later ones: to ready {sum(t[0] for t in later) / len(later):.2f} s, to evaluated "
          f"{sum(t[1] for t in later) / len(later):.2f} s; its fork server's resident memory: "
          f"{', '.join(f'{mb:.0f} MB' for mb in f.fork_server_mb)}", flush=True)


def settle(worker: int, quiet_s: float = 1.0, timeout: float = 120) -> None:
    """Wait until the worker's fork servers have prepared their other runtimes (TorchScript's, once a
    worker thread's fork server was idle: league.server.sandbox.child), which they do once per worker
    start: (c) measures the steady state, the first uploads are (b)'s."""
    deadline, quiet_since, last = time.monotonic() + timeout, time.monotonic(), None
    while time.monotonic() < deadline:
        used = sum(cpu_seconds(pid) for pid in fork_servers(worker))
        if used != last:
            last, quiet_since = used, time.monotonic()
        elif time.monotonic() - quiet_since >= quiet_s:
            return
        time.sleep(0.1)


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


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


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--rate", type=float, default=200.0, help="GET requests per second")
    parser.add_argument("--seconds", type=float, default=10.0, help="length of the GET load")
    parser.add_argument("--uploads", type=int, default=20, help="uploads at once in (c)")
    parser.add_argument("--parts", nargs="+", choices=list("abcdef"), default=list("abcdef"),
                        help="the parts to run ((b) and (c) run together, after (a))")
    parser.add_argument("--only-jobs", action="store_true", help="only (e): --parts e")
    parser.add_argument("--status-trees", type=Path, nargs="+", metavar="TREE",
                        help="only (d) with `league serve`, run from each of these source trees in turn")
    parser.add_argument("--torchscript-trees", type=Path, nargs="+", metavar="TREE",
                        help="only (f), run from each of these source trees in turn")
    parser.add_argument("--settle", type=float, default=20.0, help="seconds from a worker's start to the first "
                                                                   "upload in (f)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="league-bench-model-") as folder:
        model = thesis_actor(Path(folder))
        scripted = thesis_torchscript(Path(folder))
        if args.torchscript_trees:
            for tree in args.torchscript_trees:
                report_torchscript(bench_first_torchscript(scripted, args.episodes, args.settle, root=tree.resolve()))
            return
        if args.status_trees:
            statuses = []
            for tree in args.status_trees:
                statuses.append(bench_status(model, args.rate, args.seconds, embedded=True, root=tree.resolve()))
                report_status(statuses[-1])
            print("    p99: " + ", ".join(f"{status.root}: {status.ms['p99']:.1f} ms" for status in statuses))
            print("    API CPU per answer: " + ", ".join(f"{status.root}: {status.cpu_ms:.2f} ms"
                                                       for status in statuses))
            return
        parts = {"e"} if args.only_jobs else set(args.parts)
        if parts & {"a", "b", "c"}:  # (b) compares with (a)'s plain loop
            evaluation = bench_evaluation(model, args.episodes)
            report_evaluation(evaluation)
        if parts & {"b", "c"}:
            report_worker(bench_worker_on_one_cpu(model, args.episodes, args.uploads), evaluation.plain_s,
                          evaluation.cached_lockstep_s, evaluation.cached_sandboxed_s)
        if "d" in parts:
            report_status(bench_status(model, args.rate, args.seconds, embedded=False))
            report_status(bench_status(model, args.rate, args.seconds, embedded=True))
        if "e" in parts:
            placed = bench_evaluation_job(model, args.episodes, placement=True)
            report_job(placed)
            unplaced = bench_evaluation_job(model, args.episodes, placement=False)
            report_job(unplaced)
            print(f"    CPU placement makes the evaluation job {unplaced.seconds / placed.seconds:.1f}x faster")
        if "f" in parts:
            report_torchscript(bench_first_torchscript(scripted, args.episodes, args.settle))


def thesis_torchscript(folder: Path) -> Path:
    """The thesis-size actor of (a), scripted (torch.jit.script) as a student exports it."""
    from league.agents import export_torchscript
    from league.testing import thesis_driver

    return export_torchscript(thesis_driver(), folder / "thesis_actor.pt")


if __name__ == "__main__":
    main()
