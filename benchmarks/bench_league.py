"""Benchmark of the league server's races and championships.

    python benchmarks/bench_league.py [--quick] [--students 40] [--repeats 3] [--round-repeats 1]
                                      [--rate 200] [--seconds 10] [--backend sqlite|postgres] [--per-cpu]
                                      [--before PATH] [--round-track-seed N]

(a) a 10-car heat of thesis-size ONNX agents (5 -> 64 -> 64 -> 2), each in its own sandbox
    process, pinned to one core: from starting the 10 sandboxes to the classification, sandbox
    start and close included (league.server.jobs.race.race_in_sandboxes, as the race job runs it);
    repeated, median and range: target <= 5 s;
(b) a championship round of N students in heats of 10 (40 students: 4 heats), wall time from
    POST .../rounds to the round being done, per worker setup: one `league worker`, one on one
    CPU (`--cpus`), two, and two with their CPU placement off (1 job thread each; two workers
    split the CPUs by themselves, league/server/jobs/placement.py); each on a new championship with
    the same seed (same heats; each round's track is drawn secretly, so the runs race different
    tracks and the medians absorb it), the API started with --no-worker; evaluations are
    finished and the workers started before the round is posted, so only racing is timed.
    Target: a speed-up >= 1.7x from one worker to two on a 2-core machine; the speed-up per CPU
    (one worker on one CPU -> two workers, each on a CPU of its own) is printed beside it, since
    one worker alone races on every CPU: target >= 1.8x. --per-cpu times only these two setups
    (and skips (c)): `--backend postgres --per-cpu --round-repeats 5 --students 200` (a class's round,
    20 heats) is the per-CPU figure,
    printed beside (b0): what two CPUs give the same heats without the league (one heat alone on
    one CPU, then two at once on a CPU each), the most any league can get from them. Each round
    also says where its time went besides racing: its first heat's wait to be claimed, the
    workers' idle time between heats (the queue's share), and the tail after the first worker ran
    out of heats;
--before PATH: a checkout of this project at an earlier commit (its Cython core built, or copied
    when league/lidar.pyx is the same), e.g. the commit before the jobs table became the queue
    (`git archive e7704ee | tar -x -C /tmp/before`): (b)'s rounds are also raced by its servers, on
    a league and database of their own, the two trees taking turns round by round, and printed
    side by side (the same heats; each round a track of its own);
--round-track-seed N: every round's track is N instead of the secret draw, in both trees: the API
    is started through benchmarks/_fixed_track.py, a launcher that replaces
    league.server.course.races.draw_track_seed in that process only (nothing in league/ reads an
    override); (a) and (b0) race track N too (else TRACK_SEED); checked on each round's summary.
(c) GET /api/leaderboard at 200 requests/s on loopback (open loop) while rounds are raced by
    two workers: target p99 <= 50 ms.

--quick: 12 students, one repetition of (a), 5 s of load in (c): a check that it all works.
Everything runs on this machine: servers on 127.0.0.1 in a temporary directory, every loop
bounded in count and time, every process started here stopped at the end.
"""
from __future__ import annotations

import argparse
import contextlib
import functools
import os
import signal
import statistics
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from _league import ROOT, Deadline, League, backend, enrol, machine, measure_latency, one_core, thesis_actor

HEAT_TARGET_S = 5.0
SPEEDUP_TARGET = 1.7
PER_CPU_TARGET = 1.8
P99_TARGET_MS = 50.0
HEAT_SIZE = 10
TRACK_SEED = 3


def target_speed(k: int) -> float:
    """Student k's driver: target speeds 0.18 .. 0.27 (all finish a lap on most tracks)."""
    return 0.18 + 0.01 * (k % 10)


def student_models(folder: Path, count: int) -> list[Path]:
    return [thesis_actor(folder, f"student{k:02d}.onnx", target_speed=target_speed(k), seed=k) for k in range(count)]


def outcomes(classification: list[dict]) -> str:
    counts: dict[str, int] = {}
    for row in classification:
        counts[row["outcome"]] = counts.get(row["outcome"], 0) + 1
    return ", ".join(f"{n} {outcome}" for outcome, n in sorted(counts.items()))


# --------------------------------------------------------------------------- figures


@dataclass
class Heat:
    """(a) wall seconds of each run of the heat in sandboxes on one core."""

    cars: int
    track_seed: int
    cpu: int
    totals: list[float]  # start of the sandboxes -> classification, each run
    starts: list[float]  # the sandboxes' start, each run
    in_process_s: float  # the same race, models loaded in this process
    outcomes: str  # the first run's classification, counted
    steps: int
    identical: bool  # every run's classification equals the in-process race's

    @property
    def median_s(self) -> float:
        return statistics.median(self.totals)


@dataclass
class Ceiling:
    """(b0) the heat raced alone on one CPU, and beside itself on a second CPU (medians)."""

    cars: int
    cpus: tuple[int, int]
    runs: int
    alone_s: float
    beside_s: float

    @property
    def speedup(self) -> float:
        return 2 * self.alone_s / self.beside_s


@dataclass
class RoundRun:
    repeat: int
    setup: str  # the worker setup, after the tree's name with --before ("before: 1 worker on CPU 0")
    seconds: float
    heats_s: float  # the heats' run times, summed
    heats: str  # per heat: start, run time, worker, outcomes
    waits: HeatWaits | None = None
    track_seed: int | None = None  # the round's track, shown once the round is done


@dataclass
class HeatWaits:
    """Where a round's time went besides racing, from its jobs' times (seconds)."""

    first_claim_s: float  # the round created -> its first heat claimed
    idle_s: float  # summed over workers: one heat of theirs finished -> their next one claimed
    tail_s: float  # the first worker to run out of heats -> the round's last heat finished
    busiest_s: float  # the busiest worker's heats' run times, summed


@dataclass
class Rounds:
    """(b) a round per worker setup, `repeats` times each."""

    students: int
    heats: int
    runs: list[RoundRun]
    same_heats: bool  # every round had the same heats

    @property
    def times(self) -> dict[str, list[float]]:
        times: dict[str, list[float]] = {}
        for run in self.runs:
            times.setdefault(run.setup, []).append(run.seconds)
        return times

    @property
    def medians(self) -> dict[str, float]:
        return {setup: statistics.median(runs) for setup, runs in self.times.items()}

    @property
    def repeats(self) -> int:
        return max(run.repeat for run in self.runs)

    @property
    def trees(self) -> list[str]:
        """The source trees' prefixes of the setups ("" alone; "before: ", "this tree: " with --before)."""
        first = next(iter(pinned_setups()))
        return list(dict.fromkeys(run.setup.removesuffix(first) for run in self.runs if run.setup.endswith(first)))


@dataclass
class Leaderboard:
    """(c) GET /api/leaderboard while two workers race, milliseconds."""

    rows: int
    rate: float
    requests: int
    ms: dict[str, float]  # p50, p95, p99, max
    racing_share: float  # the share of samples in which a round was racing
    over_target: int  # requests slower than P99_TARGET_MS
    bursts: list[float]  # when the slow ones were sent, grouped (seconds from the start)
    cache_control: str


@dataclass
class LeagueRun:
    """(b) and (c) on one league."""

    backend: str
    students: int
    eval_episodes: int
    setup_s: float  # the submissions ready and evaluated
    rounds: Rounds
    leaderboard: Leaderboard | None = None  # not with --per-cpu
    ceiling: float | None = None  # (b0)'s speed-up, when measured


# --------------------------------------------------------------------------- (a) one heat, one core


def bench_heat(models: list[Path], repeats: int, track_seed: int = TRACK_SEED) -> Heat:
    from league.evaluation import race
    from league.server.jobs.race import race_in_sandboxes
    from league.server.sandbox.agent import SandboxedAgent
    from league.validation.limits import SandboxLimits

    names = [f"student{k:02d}" for k in range(len(models))]
    limits = SandboxLimits()
    totals, starts, results = [], [], []
    with one_core() as cpu:  # this process and the sandboxes it starts share one CPU
        for _ in range(repeats):
            started = []

            def start(model: Path, name: str):
                agent = SandboxedAgent(model, "onnx", limits, name=name)
                started.append(time.perf_counter())  # noqa: B023 - called in this iteration
                return agent

            begin = time.perf_counter()
            result = race_in_sandboxes([functools.partial(start, m, n) for m, n in zip(models, names)], names,
                                       seed=track_seed, env_options={})
            totals.append(time.perf_counter() - begin)
            starts.append(started[-1] - begin)
            results.append(result)
        begin = time.perf_counter()
        local = race(models, seed=track_seed, names=names)
        in_process = time.perf_counter() - begin
    return Heat(cars=len(models), track_seed=track_seed, cpu=cpu, totals=totals, starts=starts, in_process_s=in_process,
                outcomes=outcomes(results[0].classification),
                steps=max(len(car["acc"]) for car in results[0].replay["cars"]),
                identical=all(r.classification == local.classification for r in results))


def report_heat(f: Heat) -> None:
    verdict = "ok" if f.median_s <= HEAT_TARGET_S else "OVER TARGET"
    print(f"(a) {f.cars}-car heat on track {f.track_seed}, ONNX agents in sandboxes, one core (CPU {f.cpu}), "
          f"sandbox start and close included: median {f.median_s:.2f} s over {len(f.totals)} runs "
          f"(range {min(f.totals):.2f} .. {max(f.totals):.2f} s) "
          f"(target <= {HEAT_TARGET_S:g} s: {verdict})", flush=True)
    print(f"    starting the {f.cars} sandboxes: median {statistics.median(f.starts):.2f} s, racing and closing: "
          f"median {statistics.median(t - s for t, s in zip(f.totals, f.starts)):.2f} s; the same race without "
          f"sandboxes (models loaded in-process): {f.in_process_s:.2f} s", flush=True)
    print(f"    classification: {f.outcomes}, {f.steps} steps; identical to the in-process race: {f.identical}",
          flush=True)


# --------------------------------------------------------------------------- (b0) what two CPUs give at most


def race_heats_pinned(cpu: int, models: list[Path], runs: int, barrier, times, track_seed: int = TRACK_SEED) -> None:
    """In a process of its own on `cpu`: race the heat once (imports, first sandboxes), then `runs`
    times, each starting with the other processes at the barrier; each race's seconds go to `times`."""
    from league.server.jobs.race import race_in_sandboxes
    from league.server.sandbox.agent import SandboxedAgent
    from league.validation.limits import SandboxLimits

    os.sched_setaffinity(0, {cpu})  # the sandboxes started here inherit it
    names, limits = [f"student{k:02d}" for k in range(len(models))], SandboxLimits()
    starts = [functools.partial(SandboxedAgent, model, "onnx", limits, name=name) for model, name in zip(models, names)]
    for run in range(runs + 1):
        barrier.wait()
        begin = time.perf_counter()
        race_in_sandboxes(starts, names, seed=track_seed, env_options={})
        if run:
            times.put(time.perf_counter() - begin)


def bench_ceiling(models: list[Path], runs: int, track_seed: int = TRACK_SEED) -> Ceiling:
    """The per-CPU speed-up this machine allows racing, without the league: the same heat raced by one
    process on one CPU, then by two processes at once, each on a CPU of its own (nothing else
    running). Two CPUs give twice the heats only if a heat takes as long beside another as alone."""
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    first, second = sorted(os.sched_getaffinity(0))[:2]
    medians = {}
    for cpus in ([first], [first, second]):
        barrier, times = context.Barrier(len(cpus)), context.Queue()
        processes = [context.Process(target=race_heats_pinned, args=(cpu, models, runs, barrier, times, track_seed))
                     for cpu in cpus]
        for process in processes:
            process.start()
        seconds = [times.get(timeout=600) for _ in range(runs * len(cpus))]
        for process in processes:
            process.join(timeout=60)
        medians[len(cpus)] = statistics.median(seconds)
    return Ceiling(cars=len(models), cpus=(first, second), runs=runs, alone_s=medians[1], beside_s=medians[2])


def report_ceiling(f: Ceiling) -> None:
    print(f"(b0) what two CPUs give racing on this machine, without the league: a {f.cars}-car heat in sandboxes "
          f"takes {f.alone_s:.2f} s alone on CPU {f.cpus[0]}, {f.beside_s:.2f} s beside the same heat on CPU "
          f"{f.cpus[1]} (medians of {f.runs}): two CPUs race {f.speedup:.2f}x the heats of one", flush=True)


# --------------------------------------------------------------------------- (b) a round, 1 vs 2 workers


def setup_students(league: League, models: list[Path], timeout: float) -> None:
    """One student per model, each uploads theirs; return once every submission is ready and
    evaluated and no job is left (the baselines' evaluations included)."""
    with league.client() as instructor:
        tokens = enrol(instructor, [f"student{k:02d}" for k in range(len(models))])
        for token, model in zip(tokens, models):
            with league.client(token) as student, open(model, "rb") as handle:
                student.post("/api/submissions", files={"file": (model.name, handle)},
                             data={"name": model.stem}).raise_for_status()
        deadline = Deadline(timeout, "validating and evaluating the submissions")
        while True:
            submissions = instructor.get("/api/submissions", params={"all": True}).json()
            jobs = [job for status in ("queued", "running")
                    for job in instructor.get("/api/jobs", params={"status": status}).json()]
            evaluated = [s for s in submissions if s["status"] == "ready"
                         and (s["evaluation"] or {}).get("status") == "done"]
            if len(evaluated) >= len(models) and not jobs:
                break
            if any(s["status"] in ("rejected", "failed") for s in submissions):
                raise RuntimeError(f"a submission was refused: {[s for s in submissions if s['error']][:1]}")
            deadline.check(f"{len(evaluated)} evaluated, {len(jobs)} jobs queued or running")
            time.sleep(0.5)


def new_championship(client, name: str, seed: int) -> int:
    response = client.post("/api/championships", json={"name": name, "heat_size": HEAT_SIZE,
                                                        "include_baselines": False, "seed": seed})
    response.raise_for_status()
    return response.json()["id"]


def wait_round(client, championship_id: int, number: int, timeout: float, interval: float = 0.1) -> dict:
    deadline = Deadline(timeout, f"round {number} of championship {championship_id}")
    while True:
        summary = client.get(f"/api/championships/{championship_id}/rounds/{number}").json()
        if summary["status"] in ("done", "failed"):
            return summary
        deadline.check(summary)
        time.sleep(interval)


def timed_round(client, championship_id: int, timeout: float) -> tuple[float, dict]:
    begin = time.perf_counter()
    response = client.post(f"/api/championships/{championship_id}/rounds")
    response.raise_for_status()
    summary = wait_round(client, championship_id, response.json()["number"], timeout)
    seconds = time.perf_counter() - begin
    if summary["status"] != "done":
        raise RuntimeError(f"the round failed: {summary}")
    return seconds, summary


def heat_report(client, summary: dict) -> tuple[str, float]:
    """Per heat: when its job started (from the round's creation), how long it ran, in which worker
    process, and the cars' outcomes; and the sum of the heats' run times."""
    from datetime import datetime

    jobs = {job["race_id"]: job for job in client.get("/api/jobs", params={"limit": 1000}).json() if job["race_id"]}
    parts, busy, spans = [], 0.0, []
    for race_id in summary["race_ids"]:
        race, job = client.get(f"/api/races/{race_id}").json(), jobs[race_id]
        created, started, finished = (datetime.fromisoformat(t) for t in
                                      (race["created_at"], job["started_at"], job["finished_at"]))
        ran = (finished - started).total_seconds()
        busy += ran
        worker = job["worker_id"].split("/")[1]
        spans.append((worker, (started - created).total_seconds(), (finished - created).total_seconds()))
        parts.append(f"heat {race['heat']} ({len(race['entrants'])} cars): started at "
                     f"{(started - created).total_seconds():.1f} s, ran {ran:.1f} s in worker "
                     f"{worker} [{outcomes(race['classification'])}]")
    return "\n    ".join(parts), busy, heat_waits(spans)


def heat_waits(spans: list[tuple[str, float, float]]) -> HeatWaits:
    """From each heat's (worker, claimed at, finished at), seconds from the round's creation."""
    by_worker: dict[str, list[tuple[float, float]]] = {}
    for worker, start, end in spans:
        by_worker.setdefault(worker, []).append((start, end))
    idle = sum(later[0] - earlier[1] for runs in by_worker.values()
               for earlier, later in zip(sorted(runs), sorted(runs)[1:]))
    last_ends = [max(end for _, end in runs) for runs in by_worker.values()]
    return HeatWaits(first_claim_s=min(start for _, start, _ in spans), idle_s=idle,
                     tail_s=max(last_ends) - min(last_ends),
                     busiest_s=max(sum(end - start for start, end in runs) for runs in by_worker.values()))


def keep_racing(client, championship_id: int, stop: threading.Event, busy: list[bool], max_rounds: int) -> None:
    """Start the championship's next round whenever the last one is over (at most `max_rounds`),
    and sample whether a round is being raced."""
    started = 0
    while not stop.is_set():
        rounds = client.get(f"/api/championships/{championship_id}").json()["rounds"]
        racing = bool(rounds) and rounds[-1]["status"] in ("pending", "running")
        busy.append(racing)
        if not racing and started < max_rounds:
            client.post(f"/api/championships/{championship_id}/rounds").raise_for_status()
            started += 1
        stop.wait(0.5)


Setup = list[dict]  # one dict per worker process: {"cpus": "0"} and/or {"settings": {LEAGUE_*: ...}}


def pinned_setups() -> dict[str, Setup]:
    """One worker on one CPU, and two workers on a CPU each: the speed-up per CPU."""
    first, second = sorted(os.sched_getaffinity(0))[:2]
    return {f"1 worker on CPU {first}": [{"cpus": str(first)}],
            f"2 workers on CPUs {first} and {second}": [{"cpus": str(first)}, {"cpus": str(second)}]}


def worker_setups(per_cpu: bool = False) -> dict[str, Setup]:
    """The worker processes of each timed round (`per_cpu`: only the pinned ones)."""
    if per_cpu:
        return pinned_setups()
    no_placement = {"settings": {"LEAGUE_CPU_PLACEMENT": "false"}}
    return {"1 worker": [{}], "2 workers": [{}, {}], "2 workers, CPU placement off": [no_placement, no_placement],
            **pinned_setups()}


def start_workers(league: League, setup: Setup) -> None:
    for worker in setup:
        league.start_worker(wait=True, **worker)


def compare_workers(leagues: dict[str, tuple[League, object]], students: int, seed: int, repeats: int,
                    timeout: float, per_cpu: bool = False, track_seed: int | None = None) -> tuple[Rounds, int]:
    """Time the same heats (a new championship, same seed; each round a track of its own) with each
    worker setup, `repeats` times, alternating; with several leagues (name -> league, its instructor's
    client: --before), each setup on each in turn; `track_seed`: the track the leagues' APIs were
    started to fix (checked). Returns the rounds and the last league's last championship."""
    runs, shapes = [], set()
    for repeat in range(repeats):
        for setup, workers in worker_setups(per_cpu).items():
            for tree, (league, client) in leagues.items():
                league.stop_workers()
                start_workers(league, workers)
                championship_id = new_championship(client, f"{setup}, run {repeat + 1}", seed)
                seconds, summary = timed_round(client, championship_id, timeout)
                heats, busy, waits = heat_report(client, summary)
                if track_seed is not None and summary.get("track_seed") != track_seed:
                    raise RuntimeError(f"{tree}the round raced track {summary.get('track_seed')}, not {track_seed}")
                runs.append(RoundRun(repeat=repeat + 1, setup=f"{tree}{setup}", seconds=seconds, heats_s=busy,
                                     heats=heats, waits=waits, track_seed=summary.get("track_seed")))
                shapes.add(str(summary["heats"]))
    return Rounds(students=students, heats=len(summary["heats"]), runs=runs, same_heats=len(shapes) == 1), \
        championship_id


def report_rounds(f: Rounds, per_cpu: bool = False, ceiling: float | None = None) -> None:
    seeds = {run.track_seed for run in f.runs}
    tracks = (f"every round on track {next(iter(seeds))} (--round-track-seed)" if len(seeds) == 1
              else "each round's track drawn secretly")
    print(f"(b) a round of {f.students} students in heats of <= {HEAT_SIZE}, from POST .../rounds to the round done, "
          f"per worker setup (same seed: same heats; {tracks}):")
    for run in f.runs:
        w = run.waits
        print(f"    run {run.repeat}, {run.setup}: {run.seconds:.1f} s (the heats ran {run.heats_s:.1f} s in all; "
              f"first heat claimed after {w.first_claim_s:.2f} s, workers idle between heats {w.idle_s:.2f} s "
              f"in all, the busiest worker's heats {w.busiest_s:.1f} s, the last heat finished {w.tail_s:.1f} s "
              f"after the other worker's)\n    {run.heats}")
    if not f.same_heats:
        print("    warning: the rounds differ in heats")
    medians, times = f.medians, f.times
    print(f"    {f.heats} heats, median over {f.repeats} run(s) (range):")
    for setup, runs in times.items():
        queue = statistics.median(r.waits.first_claim_s + r.waits.idle_s for r in f.runs if r.setup == setup)
        print(f"      {setup}: {medians[setup]:.1f} s ({min(runs):.1f} .. {max(runs):.1f} s); waiting for the "
              f"queue (first claim + idle between heats) {queue:.2f} s")
    for tree in f.trees:
        one_pinned, two_pinned = (medians[tree + setup] for setup in pinned_setups())
        verdict = "ok" if one_pinned / two_pinned >= PER_CPU_TARGET else "UNDER TARGET"
        print(f"    {tree}per CPU ({' -> '.join(pinned_setups())}): speed-up {one_pinned / two_pinned:.2f}x "
              f"(target >= {PER_CPU_TARGET:g}x: {verdict})")
        if ceiling:
            print(f"    that is {one_pinned / two_pinned / ceiling:.0%} of the {ceiling:.2f}x that two CPUs give the "
                  f"same heats without the league (b0)")
    if not per_cpu:
        tree = f.trees[-1]  # this tree's
        one, two, two_unplaced = (medians[tree + setup] for setup in
                                  ("1 worker", "2 workers", "2 workers, CPU placement off"))
        one_pinned = medians[tree + next(iter(pinned_setups()))]
        verdict = "ok" if one / two >= SPEEDUP_TARGET else "UNDER TARGET"
        print(f"    1 -> 2 workers (no pinning): speed-up {one / two:.2f}x (target >= {SPEEDUP_TARGET:g}x: {verdict}); "
              f"without CPU placement {one / two_unplaced:.2f}x; one worker alone races on every CPU, "
              f"{one_pinned / one:.2f}x faster than on one", flush=True)


def bench_league(models: list[Path], *, backend_kind: str, eval_episodes: int, rate: float, seconds: float,
                 seed: int, round_repeats: int, per_cpu: bool = False, before: Path | None = None,
                 round_track_seed: int | None = None) -> LeagueRun:
    import numpy as np

    round_timeout = 60 + 30 * len(models)  # generous: a heat takes seconds
    trees = {"before: ": before, "this tree: ": ROOT} if before else {"": ROOT}
    with contextlib.ExitStack() as stack:
        leagues, setup_s = {}, 0.0
        for name, root in trees.items():  # a league and database each: the trees' schemas may differ
            tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="league-bench-")))
            urls = stack.enter_context(backend(backend_kind, tmp))
            settings = {**urls, "LEAGUE_EVAL_EPISODES": str(eval_episodes), "LEAGUE_QUOTA_PER_DAY": "10",
                        "LEAGUE_WORKER_THREADS": "1", "LEAGUE_CPU_SLOTS_DIR": str(tmp / "cpu-slots")}
            league = stack.enter_context(League(tmp, embedded=False, settings=settings, root=root,
                                                round_track_seed=round_track_seed))
            leagues[name] = league, stack.enter_context(league.client())
            begin = time.perf_counter()
            for _ in range(2):
                league.start_worker()
            setup_students(league, models, timeout=120 + 20 * len(models))
            league.stop_workers()
            setup_s += time.perf_counter() - begin
        league, client = leagues[next(reversed(leagues))]  # this tree's: (c)

        # (b) the same heats (same seed; each round a track of its own) with one worker, then with two
        rounds, two_id = compare_workers(leagues, len(models), seed, round_repeats, round_timeout, per_cpu,
                                         round_track_seed)
        for other, _ in leagues.values():
            other.stop_workers()
        figures = LeagueRun(backend=backend_kind, students=len(models), eval_episodes=eval_episodes,
                            setup_s=setup_s, rounds=rounds)
        if per_cpu:
            return figures
        start_workers(league, worker_setups()["2 workers"])  # (c) runs with two workers

        # (c) leaderboard latency while the two workers race rounds
        stop, busy = threading.Event(), []
        loader = threading.Thread(target=keep_racing, args=(client, two_id, stop, busy, 20))
        loader.start()
        try:
            wait_running = Deadline(60, "the next round to start racing")
            while True:
                rounds = client.get(f"/api/championships/{two_id}").json()["rounds"]
                if len(rounds) >= 2 and rounds[-1]["status"] == "running":
                    break
                wait_running.check(rounds[-1:])
                time.sleep(0.2)
            time.sleep(1.0)  # sandboxes started, cars on the track
            sent: list[float] = []
            latencies = np.array(measure_latency(league.url, None, "/api/leaderboard", rate, seconds,
                                                 sent=sent)) * 1000
        finally:
            stop.set()
            loader.join()
        answer = client.get("/api/leaderboard")
    p50, p95, p99 = np.percentile(latencies, [50, 95, 99])
    figures.leaderboard = Leaderboard(
        rows=answer.json()["total"], rate=rate, requests=len(latencies),
        ms={"p50": float(p50), "p95": float(p95), "p99": float(p99), "max": float(latencies.max())},
        racing_share=float(np.mean(busy)), over_target=int(np.sum(latencies > P99_TARGET_MS)),
        bursts=slow_bursts(np.array(sent), latencies, P99_TARGET_MS),
        cache_control=answer.headers.get("cache-control", ""))
    return figures


def report_leaderboard(f: Leaderboard) -> None:
    verdict = "ok" if f.ms["p99"] <= P99_TARGET_MS else "OVER TARGET"
    print(f"(c) GET /api/leaderboard ({f.rows} rows), {f.requests} requests at {f.rate:g}/s while 2 workers race:")
    print(f"    p50 {f.ms['p50']:.1f} ms, p95 {f.ms['p95']:.1f} ms, p99 {f.ms['p99']:.1f} ms, max {f.ms['max']:.1f} ms "
          f"(target p99 <= {P99_TARGET_MS:g} ms: {verdict}); a round was racing in {100 * f.racing_share:.0f}% of the "
          f"samples; {f.over_target} requests over {P99_TARGET_MS:g} ms")
    if f.bursts:
        print(f"    the slow requests came in {len(f.bursts)} burst(s) (sent at "
              f"{', '.join(f'{t:.1f}' for t in f.bursts)} s; the answer says Cache-Control: {f.cache_control!r})")


def report_league(f: LeagueRun, per_cpu: bool = False) -> None:
    print(f"    {f.backend} backend; {f.students} submissions ready and evaluated ({f.eval_episodes}-episode "
          f"evaluations) in {f.setup_s:.0f} s")
    report_rounds(f.rounds, per_cpu, f.ceiling)
    if f.leaderboard:
        report_leaderboard(f.leaderboard)


def slow_bursts(sent, latencies_ms, threshold_ms: float, gap_s: float = 0.3) -> list[float]:
    """When the requests slower than the threshold were sent, grouped: a group starts after a gap
    of `gap_s` without slow requests (a periodic pattern points at the response cache's expiry)."""
    times = sorted(sent[latencies_ms > threshold_ms])
    return [t for k, t in enumerate(times) if k == 0 or t - times[k - 1] > gap_s]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     epilog="\n".join(__doc__.splitlines()[4:]),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true",
                        help="a fast check: 12 students, 1 run of (a), 5 s of load in (c)")
    parser.add_argument("--students", type=int, help="students in the round of (b) and (c) (default 40, quick 12)")
    parser.add_argument("--repeats", type=int, help="runs of the heat of (a) (default 3, quick 1)")
    parser.add_argument("--rate", type=float, default=200.0, help="GET /api/leaderboard per second in (c)")
    parser.add_argument("--seconds", type=float, help="length of the GET load in (c) (default 10, quick 5)")
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite",
                        help="sqlite: an SQLite database (default); postgres: the local PostgreSQL "
                             "(LEAGUE_BENCH_PG, default postgresql://postgres@127.0.0.1:5432/test)")
    parser.add_argument("--eval-episodes", type=int, default=1, help="episodes of each submission's evaluation")
    parser.add_argument("--seed", type=int, default=7, help="the championships' seed (their tracks and heats)")
    parser.add_argument("--round-repeats", type=int, default=1,
                        help="rounds per worker setup in (b), the setups alternating; medians are compared")
    parser.add_argument("--skip-heat", action="store_true", help="skip (a)")
    parser.add_argument("--skip-round", action="store_true", help="skip (b) and (c)")
    parser.add_argument("--before", type=Path, help="a checkout of this project at an earlier commit: (b) races its "
                                                    "rounds too, side by side")
    parser.add_argument("--round-track-seed", type=int, metavar="N",
                        help="every round's track N in both trees (the API started through benchmarks/_fixed_track.py;"
                             " the product keeps drawing it secretly); (a) and (b0) race it too")
    parser.add_argument("--per-cpu", action="store_true",
                        help="(b) with one worker on one CPU and two on a CPU each only, and no (c)")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # cleanup (servers, temporary files) on SIGTERM too
    students = args.students or (12 if args.quick else 40)
    repeats = args.repeats or (1 if args.quick else 3)
    seconds = args.seconds or (5.0 if args.quick else 10.0)
    if students < HEAT_SIZE:
        parser.error(f"--students must be at least {HEAT_SIZE}")
    if not args.skip_round and len(os.sched_getaffinity(0)) < 2:
        parser.error("(b) compares one worker with two on CPUs of their own: this process may use one CPU "
                     "(use --skip-round)")
    if args.round_track_seed is not None and not 0 <= args.round_track_seed < 2**53:
        parser.error(f"--round-track-seed: a round's track seed is in [0, 2**53), not {args.round_track_seed}")
    heat_track = TRACK_SEED if args.round_track_seed is None else args.round_track_seed
    print(machine(), flush=True)
    with tempfile.TemporaryDirectory(prefix="league-bench-models-") as folder:
        models = student_models(Path(folder), students)
        if not args.skip_heat:
            report_heat(bench_heat(models[:HEAT_SIZE], repeats, heat_track))
        ceiling = None
        if args.per_cpu and not args.skip_round:
            ceiling = bench_ceiling(models[:HEAT_SIZE], repeats, heat_track)
            report_ceiling(ceiling)
        if not args.skip_round:
            figures = bench_league(models, backend_kind=args.backend, eval_episodes=args.eval_episodes, rate=args.rate,
                                   seconds=seconds, seed=args.seed, round_repeats=max(1, args.round_repeats),
                                   per_cpu=args.per_cpu, before=args.before, round_track_seed=args.round_track_seed)
            figures.ceiling = ceiling.speedup if ceiling else None
            report_league(figures, args.per_cpu)
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)


if __name__ == "__main__":
    main()
