"""Benchmark of the student toolkit (issues 3 and 12), on one core.

    python benchmarks/bench_toolkit.py [--episodes 100] [--cars 10] [--out DIR]

(a) 100 episodes of a thesis-size actor (5 -> 64 -> 64 -> 2, tanh) exported to ONNX, every
    option on, three ways, same file and same tracks, in the same run:
    - the plain loop a student (and the thesis) writes: gymnasium.make + ONNX Runtime, one
      session call per step, one episode after another;
    - `run_episode` one episode at a time (metrics_run before issue 12);
    - `metrics_run`, in lockstep (one call per step for every running episode), with the track
      cache empty (as a new worker process) and warm (every later submission of a course).
    Target: lockstep metrics_run >= 4x the plain loop with the tracks cached, the empty cache on a
    line of its own (issues 12, 33), <= 10 s (issue 3).
(b) How many of those episodes end differently in lockstep than one at a time: ONNX Runtime's
    batched matmuls sum in another order, so actions may differ in the last bits.
(c) a 10-car race of ONNX agents (--cars): target <= 2 s;
(d) saving that race's GIF: target <= 30 s.
(e) the same 100 episodes of exports fixed to batch size 1 (many students' files; a quarter of the
    deadline rush's), as evaluated before (row by row: a model call per running episode per step)
    and now (ONNX: the graph given a free batch dimension when it answers a batch as it answers
    each row; TorchScript: the rows in one no_grad and checked once).

Times are CPU time of this process (time.process_time): on a shared machine, the other
processes' time slices on this core are not counted.

The actor is `league.testing.thesis_driver`: real 64-unit matmuls, wired to drive like
the heuristic so that episodes are full laps (a random actor would crash in a few steps and
flatter the figures).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from _league import pin_to_one_core, plain_loop

TARGETS = {"metrics_run": 10.0, "race": 2.0, "gif": 30.0}  # seconds
SPEED_UP_TARGET = 4.0  # lockstep metrics_run against the plain loop
ACTOR = 5  # the actor of (a), (b): target speed 0.25, as the heuristic


@dataclass
class ToolkitFigures:
    """CPU seconds of each part (see the module's docstring), and what each run did."""

    episodes: int
    # (a)
    plain_s: float
    plain_completed: int
    one_at_a_time_s: float
    cold_s: float  # metrics_run in lockstep, the track cache empty
    warm_s: float  # the same, tracks cached
    steps: int
    completed: int
    cache_hits: int
    # (b)
    outcomes_changed: int
    outcome_or_steps_changed: int
    largest_return_difference: float
    # (c), (d)
    cars: int
    race_s: float
    race_steps: int
    finishers: int
    replay_kib: float
    gif_s: float
    gif_kib: float
    # (e)
    onnx_fixed_before_s: float
    onnx_fixed_after_s: float
    onnx_fixed_path: str  # how the loader's agent runs a fixed-batch ONNX file
    torchscript_fixed_before_s: float
    torchscript_fixed_after_s: float


def export_actor(folder: Path, k: int) -> Path:
    """Actor k holds 0.20 + 0.01 k: different speed targets make a real race (the cars spread out)."""
    from league.agents import export_onnx
    from league.testing import thesis_driver

    return export_onnx(thesis_driver(seed=k, target_speed=0.20 + 0.01 * k), folder / f"actor_{k}.onnx")


def cpu_time(work):
    """The result of work() and the CPU seconds of this process it took."""
    start = time.process_time()
    result = work()
    return result, time.process_time() - start


def measure(episodes: int, out: Path, cars: int = 10) -> ToolkitFigures:
    """Every part, its files (actors, replay, GIF) written to `out`."""
    import league
    from league.agents import load_agent
    from league.evaluation import episode_seeds, metrics_run, race, run_episode, save_replay
    from league.track import set_track_cache_size, track_cache_info
    from league.render import animate_replay

    paths = [export_actor(out, k) for k in range(cars)]
    actor = paths[ACTOR] if cars > ACTOR else export_actor(out, ACTOR)
    agent = load_agent(actor)
    seeds = episode_seeds(0, episodes)
    plain_completed, plain = cpu_time(lambda: plain_loop(actor, seeds))
    env = league.MicroRacerEnv()
    alone, one_at_a_time = cpu_time(lambda: [run_episode(env, agent, seed) for seed in seeds])
    set_track_cache_size(max(128, episodes))  # empties the cache: the first run draws every track
    result, cold = cpu_time(lambda: metrics_run(agent, episodes=episodes, seed=0))
    _, warm = cpu_time(lambda: metrics_run(agent, episodes=episodes, seed=0))
    changed = [(a, b) for a, b in zip(alone, result.episodes) if (a.outcome, a.steps) != (b.outcome, b.steps)]

    racers = [load_agent(path, name=f"actor {k} (target {0.20 + 0.01 * k:.2f})") for k, path in enumerate(paths)]
    race_result, race_s = cpu_time(lambda: race(racers, seed=1))
    replay_path = save_replay(race_result, out / "race.json")
    gif, gif_s = cpu_time(lambda: animate_replay(race_result.replay, save=out / "race.gif"))
    fixed = fixed_batch_exports(out, seeds)
    return ToolkitFigures(
        episodes=episodes, plain_s=plain, plain_completed=plain_completed, one_at_a_time_s=one_at_a_time,
        cold_s=cold, warm_s=warm, steps=sum(e.steps for e in result.episodes), completed=result.completed,
        cache_hits=track_cache_info().hits, outcomes_changed=sum(a.outcome != b.outcome for a, b in changed),
        outcome_or_steps_changed=len(changed),
        largest_return_difference=max(abs(a.episode_return - b.episode_return)
                                      for a, b in zip(alone, result.episodes)),
        cars=cars, race_s=race_s, race_steps=max(len(car.x) - 1 for car in race_result.cars),
        finishers=sum(row["outcome"] == "finished" for row in race_result.classification),
        replay_kib=replay_path.stat().st_size / 1024, gif_s=gif_s, gif_kib=gif.stat().st_size / 1024, **fixed)


def fixed_batch_exports(out: Path, seeds: list[int]) -> dict:
    """(e): the row-by-row path (the loader's agent forced back to it) beside the loader's own."""
    import numpy as np

    from league.agents import Agent, OnnxAgent, TorchAgent, _onnx_session, import_onnxruntime, load_agent
    from league.evaluation import metrics_run
    from league.testing import onnx_fixed_batch, thesis_driver, torchscript_fixed_batch

    n = len(seeds)
    onnx_file = onnx_fixed_batch(thesis_driver(target_speed=0.25), out / "fixed.onnx")
    as_exported = OnnxAgent(_onnx_session(import_onnxruntime(), onnx_file), 5, "row by row", fixed_batch=True, rank=2,
                            input_dtype=np.float32)
    _, onnx_before = cpu_time(lambda: metrics_run(as_exported, episodes=n, seed=0))
    agent = load_agent(onnx_file)
    _, onnx_after = cpu_time(lambda: metrics_run(agent, episodes=n, seed=0))
    onnx_path = "row by row" if agent.fixed_batch else "free batch"
    ts_file = torchscript_fixed_batch(thesis_driver(target_speed=0.25), out / "fixed.pt")
    agent = load_agent(ts_file)

    class EachRowOnItsOwn(TorchAgent):
        _act_rows = Agent._act_rows  # the generic path: a no_grad and a check per row

    each_row = EachRowOnItsOwn(agent._module, 5, "each row on its own")
    each_row.fixed_batch = True
    _, ts_before = cpu_time(lambda: metrics_run(each_row, episodes=n, seed=0))
    _, ts_after = cpu_time(lambda: metrics_run(agent, episodes=n, seed=0))
    return {"onnx_fixed_before_s": onnx_before, "onnx_fixed_after_s": onnx_after, "onnx_fixed_path": onnx_path,
            "torchscript_fixed_before_s": ts_before, "torchscript_fixed_after_s": ts_after}


def row(label: str, seconds: float, target: float | None = None) -> str:
    verdict = "" if target is None else f"   (target <= {target:g} s: {'ok' if seconds <= target else 'OVER TARGET'})"
    return f"{label:<58} {seconds:7.2f} s{verdict}"


def report(figures: ToolkitFigures, kept_in: Path | None = None) -> None:
    f, n = figures, figures.episodes
    print(row(f"(a) plain loop, gym.make + ONNX Runtime, {n} episodes", f.plain_s))
    print(row("    run_episode, one episode at a time (before issue 12)", f.one_at_a_time_s))
    print(row("    metrics_run in lockstep, empty track cache", f.cold_s, TARGETS["metrics_run"]))
    print(row("    metrics_run in lockstep, tracks cached", f.warm_s))
    print(f"    {f.steps} steps, completed {f.completed}/{n} (plain loop: {f.plain_completed}), {f.cache_hits} cache "
          f"hits")
    warm = f.plain_s / f.warm_s
    print(f"    lockstep with the tracks cached (every later evaluation of a seed, issue 33): {warm:.1f}x the plain "
          f"loop (target >= {SPEED_UP_TARGET:g}x: {'ok' if warm >= SPEED_UP_TARGET else 'NOT MET'})")
    print(f"    lockstep with an empty track cache (a new process's first evaluation): {f.plain_s / f.cold_s:.1f}x")
    print(f"(b) lockstep against one at a time: {f.outcomes_changed} of {n} episodes change outcome, "
          f"{f.outcome_or_steps_changed} change outcome or steps; largest return difference "
          f"{f.largest_return_difference:.2e}")
    print(row(f"(c) {f.cars}-car race, ONNX agents", f.race_s, TARGETS["race"]))
    print(f"    {f.race_steps} steps, {f.finishers} finishers, replay {f.replay_kib:.0f} KiB")
    print(row("(d) saving the race's GIF", f.gif_s, TARGETS["gif"]))
    print(f"    {f.gif_kib:.0f} KiB" + (f", kept in {kept_in}" if kept_in else ""))
    print(row(f"(e) ONNX fixed to batch 1, {n} episodes: row by row (before)", f.onnx_fixed_before_s))
    print(row(f"    the loader's agent ({f.onnx_fixed_path})", f.onnx_fixed_after_s))
    print(f"    {f.onnx_fixed_before_s / f.onnx_fixed_after_s:.1f}x")
    print(row("    TorchScript fixed to batch 1: each row checked on its own (before)", f.torchscript_fixed_before_s))
    print(row("    the rows in one no_grad, checked once", f.torchscript_fixed_after_s))
    print(f"    {f.torchscript_fixed_before_s / f.torchscript_fixed_after_s:.1f}x")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--cars", type=int, default=10, help="cars of the race in (c) and (d)")
    parser.add_argument("--out", type=Path, default=None, help="where to keep the GIF and replay (default: a temp dir)")
    args = parser.parse_args(argv)
    print(f"toolkit benchmark, {pin_to_one_core()}")
    with tempfile.TemporaryDirectory() as scratch:
        out = args.out or Path(scratch)
        out.mkdir(parents=True, exist_ok=True)
        report(measure(args.episodes, out, args.cars), kept_in=args.out)


if __name__ == "__main__":
    main()
