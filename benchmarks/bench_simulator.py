"""Simulator speed: reset, one-car step, lidar, PettingZoo step with 64 cars, the batched interface,
and the vector env against Gymnasium's SyncVectorEnv.

    python benchmarks/bench_simulator.py [--quick] [--reference PATH] [--before PATH]

Prints medians over many calls (one process, one thread, pinned to one core). Cars are driven by
SPEC's heuristic driver, computed for all cars at once in numpy, so they stay on the road; only
the step calls are timed, never the resets, except in the vector env rows, which time whole
loops (driver, steps and the autoresets with their new tracks) as a training loop runs them, and
beside them their step calls alone (the driver, the same numpy code on both sides, left out);
at 8 envs also the loop on a pool of 8 tracks, the new tracks' share it shows (the same on both
sides) and the ratio to sync that share leaves (new_tracks_share).
Resets and loops are timed in CPU time of the process (time.process_time): on a shared machine
the other processes' time slices on this core are not counted; microsecond calls use the wall
clock (a median over thousands of calls).

--reference PATH: a checkout of the reference implementation (github.com/asperti/MicroRacer);
    its reset and step are timed beside ours, in a subprocess (it builds its lidar with
    pyximport on first use). Its column is skipped without it.
--before PATH: a built checkout of this project at an earlier commit (e.g. `git worktree add
    /tmp/before <commit> && cd /tmp/before && python setup.py build_ext --inplace`); its reset
    is timed beside ours, in a subprocess, in the same run.

Targets: reset <= 0.5 ms and >= 300x the reference's (issue 33; 1 ms and 150x in issue 12); step
<= 5 us, lidar <= 1.5 us, PettingZoo 64 cars >= 250k car-steps/s, batched >= 1M car-steps/s (issue
2); vector env with a new track every episode >= 5x make_vec(..., "sync") (issues 12, 33), from a
track pool >= 1M steps/s (issue 12).
"""
from __future__ import annotations

import argparse
import functools
import json
import os
import subprocess
import sys
import time
import timeit
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

import league
from _league import pin_to_one_core
from league import lidar, render
from league.agents import heuristic_actions as heuristic

RESET_SNIPPET = """
import contextlib, io, json, sys, time
import numpy as np
with contextlib.redirect_stdout(io.StringIO()):  # the reference prints as it works
    {setup}
    reset()
    samples = []
    for _ in range({n}):
        t0 = time.process_time()
        reset()
        samples.append(time.process_time() - t0)
    {step_setup}
print(json.dumps({{"reset_us": float(np.median(samples) * 1e6), "step_us": step_us}}))
"""
REFERENCE_SETUP = """import tracks
    racer = tracks.Racer()
    reset = racer.reset"""
REFERENCE_STEP = """racer.reset()
    steps = []
    for _ in range(2000):
        t0 = time.perf_counter()
        state, reward, done = racer.step([0.0, 0.0])  # straight on
        steps.append(time.perf_counter() - t0)
        if done:
            racer.reset()
    step_us = float(np.median(steps) * 1e6)"""
BEFORE_SETUP = """import league
    env = league.MicroRacerEnv()
    env.reset(seed=0)
    reset = env.reset"""


def median_us(samples) -> float:
    return float(np.median(samples) * 1e6)


def bench_reset(n: int) -> float:
    env = league.MicroRacerEnv()
    env.reset(seed=0)
    samples = []
    for _ in range(n):
        t0 = time.process_time()
        env.reset()
        samples.append(time.process_time() - t0)
    return median_us(samples)


def bench_elsewhere(path: Path, setup: str, n: int, step_setup: str = "step_us = None") -> dict:
    """Time a reset (and a step) of another checkout in a subprocess on this core."""
    code = RESET_SNIPPET.format(setup=setup, step_setup=step_setup, n=n)
    env = {**os.environ, "PYTHONPATH": str(path), "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, "-c", code], cwd=path, env=env, capture_output=True, text=True, timeout=3600)
    if done.returncode != 0:
        raise SystemExit(f"timing {path} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def bench_step(env, n: int) -> float:
    """Median time of env.step with the heuristic's action (computed outside the timing)."""
    obs, _ = env.reset(seed=0)
    samples = []
    while len(samples) < n:
        action = heuristic(obs[None])[0]
        t0 = time.perf_counter()
        obs, _, terminated, truncated, _ = env.step(action)
        samples.append(time.perf_counter() - t0)
        if terminated or truncated:
            obs, _ = env.reset()
    return median_us(samples)


def bench_lidar(n: int) -> float:
    env = league.MicroRacerEnv()
    env.reset(seed=0)
    track = env.unwrapped.track
    x, y = track.start_position
    grid, heading = track.grid, track.start_heading
    return min(timeit.repeat(lambda: lidar.lidar(grid, x, y, heading), number=n, repeat=5)) / n * 1e6


def bench_frame(n_cars: int, n: int) -> float:
    """Median time of one rgb_array frame (650 x 650 px) with n cars, each with a 600-point trail."""
    env = league.MicroRacerEnv()
    env.reset(seed=0)
    track = env.unwrapped.track
    trails = [track.midline(np.linspace(0, 2 * np.pi * k / n_cars, 600)) for k in range(1, n_cars + 1)]
    xs, ys = [t[-1, 0] for t in trails], [t[-1, 1] for t in trails]
    render.render_frame(track, xs, ys, np.zeros(n_cars), trails)  # the background is drawn once per track
    return median_us(timeit.repeat(lambda: render.render_frame(track, xs, ys, np.zeros(n_cars), trails),
                                   number=1, repeat=n))


def bench_parallel(n_cars: int, seconds: float, batched: bool) -> float:
    """Car-steps per second of running cars, timing only the step calls."""
    penv = league.make_parallel_env(n_cars=n_cars)
    seed, elapsed, car_steps = 0, 0.0, 0
    while elapsed < seconds:
        observations, _ = penv.reset(seed=seed)
        seed += 1
        obs = np.stack([observations[a] for a in penv.possible_agents])
        while penv.agents:
            actions = heuristic(obs)
            running = len(penv.agents)
            if batched:
                t0 = time.perf_counter()
                obs, _, _, _ = penv.step_arrays(actions)
                elapsed += time.perf_counter() - t0
            else:
                action_dict = {a: actions[int(a[4:])] for a in penv.agents}
                t0 = time.perf_counter()
                observations, _, _, _, _ = penv.step(action_dict)
                elapsed += time.perf_counter() - t0
                for a, o in observations.items():
                    obs[int(a[4:])] = o
            car_steps += running
    return car_steps / elapsed


def bench_vector(make, seconds: float) -> tuple[float, float]:
    """Sub-env steps per second of a whole training-style loop (driver, step, autoresets), and
    of its `step` calls alone (autoresets included; the driver, the same on both sides, not)."""
    venv = make()
    obs, _ = venv.reset(seed=0)
    steps, in_step, start = 0, 0.0, time.process_time()
    while time.process_time() - start < seconds:
        for _ in range(50):
            actions = heuristic(obs)
            t0 = time.process_time()
            obs, *_ = venv.step(actions)
            in_step += time.process_time() - t0
        steps += 50 * venv.num_envs
    rate = steps / (time.process_time() - start)
    venv.close()
    return rate, steps / in_step


def new_tracks_share(sync: float, fresh: float, seconds: float, reset_us: float) -> list[Row]:
    """What the new tracks cost the 8-env loops, and what that leaves of the ratio to sync.

    Both loops drive the same cars on the same tracks (seeds 0..7, the same driver), so they pay
    the same new tracks per step: the fresh loop's time per step less that of a loop on a pool
    of 8 tracks (no new track, the cars still on 8 maps). Take that from both sides and the ratio
    is what the rest of the loop allows; scale it with the reset, and the reset that 5x needs.
    """
    pool = bench_vector(functools.partial(league.make_vector_env, num_envs=8, track_pool=8), seconds)[0]
    sync_us, fresh_us, pool_us = 8e6 / sync, 8e6 / fresh, 8e6 / pool
    tracks_us = max(fresh_us - pool_us, 0.0)

    def ratio(reset: float) -> float:  # the 8-env ratio with this reset time instead of today's
        scaled = tracks_us * reset / reset_us
        return (sync_us - tracks_us + scaled) / (pool_us + scaled)

    needed = (sync_us - tracks_us - 5 * pool_us) / 4 * reset_us / tracks_us if tracks_us else float("nan")
    return [
        Row("league.vector_env, 8 envs, pool of 8 tracks", pool, "steps/s", "(no new tracks: the cars alone)"),
        Row("  8 envs: new tracks' share of the loop", 100 * tracks_us / fresh_us, "%",
            f"({tracks_us:.1f} of {fresh_us:.1f} us a step; sync's {sync_us:.1f} us hold the same)"),
        Row("  8 envs: the ratio to sync were new tracks free", ratio(0.0), "x"),
        Row("  8 envs: the ratio to sync with a reset of 0.5 ms", ratio(500.0), "x", "(the reset target above)"),
        Row("  8 envs: the reset 5x needs", needed, "us", "(negative: none would do)"),
    ]


@dataclass
class Row:
    """One figure, printed as a row: what, its value in `unit`, and its target or comparison."""

    name: str
    value: float
    unit: str
    note: str = ""


def measure(scale: float = 1.0, reference: Path | None = None, before: Path | None = None) -> list[Row]:
    """Every figure, in print order; `scale` multiplies every count and duration (0.1: --quick)."""
    reset_us = bench_reset(max(3, int(300 * scale)))
    rows = [Row("reset, new random track, all options on", reset_us, "us", "<= 500")]
    if before:
        before_us = bench_elsewhere(before, BEFORE_SETUP, max(3, int(300 * scale)))["reset_us"]
        rows.append(Row("  the same, --before checkout", before_us, "us", f"({before_us / reset_us:.1f}x ours)"))
    if reference:
        ref = bench_elsewhere(reference, REFERENCE_SETUP, max(3, int(30 * scale)), REFERENCE_STEP)
        rows.append(Row("  the same, reference implementation", ref["reset_us"], "us",
                        f"({ref['reset_us'] / reset_us:.0f}x ours, target >= 300x)"))
    steps = max(10, int(20000 * scale))
    rows += [
        Row("MicroRacerEnv.step, one car", bench_step(league.MicroRacerEnv(), steps), "us", "<= 5"),
        Row("gym.make(...).step (with Gymnasium's wrappers)", bench_step(gym.make("league/MicroRacer-v0"), steps),
            "us"),
    ]
    if reference:
        rows.append(Row("  Racer.step of the reference implementation", ref["step_us"], "us"))
    frames = max(1, int(200 * scale))
    rows += [
        Row("lidar of one car (19 rays)", bench_lidar(max(10, int(100000 * scale))), "us", "<= 1.5"),
        Row("rgb_array frame, 1 car with a 600-point trail", bench_frame(1, frames), "us"),
        Row("rgb_array frame, 10 cars with 600-point trails", bench_frame(10, frames), "us", "<= 30000"),
        Row("PettingZoo step, 64 cars", bench_parallel(64, 3 * scale, batched=False), "car-steps/s", ">= 250000"),
        Row("batched step_arrays, 64 cars", bench_parallel(64, 3 * scale, batched=True), "car-steps/s", ">= 1000000"),
    ]
    seconds = 4 * scale
    sync, sync_steps = bench_vector(
        lambda: gym.make_vec("league/MicroRacer-v0", num_envs=8, vectorization_mode="sync"), seconds)
    rows.append(Row('make_vec(..., "sync"), 8 envs, new track every episode', sync, "steps/s"))
    rows.append(Row("  its step calls alone", sync_steps, "steps/s"))
    for num_envs in (8, 64, 256):
        fresh, fresh_steps = bench_vector(functools.partial(league.make_vector_env, num_envs=num_envs), seconds)
        rows.append(Row(f"league.vector_env, {num_envs} envs, new track every episode", fresh, "steps/s",
                        f"{fresh / sync:.1f}x sync, target >= 5x"))
        rows.append(Row("  its step calls alone", fresh_steps, "steps/s", f"{fresh_steps / sync_steps:.1f}x sync's"))
        if num_envs == 8:
            rows += new_tracks_share(sync, fresh, seconds, reset_us)
    for num_envs, pool_size in ((256, 8), (256, 100)):
        pool, _ = bench_vector(functools.partial(league.make_vector_env, num_envs=num_envs, track_pool=pool_size),
                               seconds)
        rows.append(Row(f"league.vector_env, {num_envs} envs, pool of {pool_size} tracks", pool, "steps/s",
                        "target >= 1000000"))
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    parser.add_argument("--reference", type=Path, help="a checkout of github.com/asperti/MicroRacer, timed beside ours")
    parser.add_argument("--before", type=Path, help="a built checkout of this project at an earlier commit")
    args = parser.parse_args(argv)
    print(f"simulator benchmark, {pin_to_one_core()}")
    for row in measure(0.1 if args.quick else 1.0, args.reference, args.before):
        print(f"{row.name:<58} {row.value:>12,.1f}  {row.unit:<12} {row.note}".rstrip())


if __name__ == "__main__":
    main()
