"""Benchmark of the student toolkit (issues 3 and 12), on one core.

    python benchmarks/bench_toolkit.py [--episodes 100] [--out DIR]

(a) 100 episodes of a thesis-size actor (5 -> 64 -> 64 -> 2, tanh) exported to ONNX, every
    option on, three ways, same file and same tracks, in the same run:
    - the plain loop a student (and the thesis) writes: gymnasium.make + ONNX Runtime, one
      session call per step, one episode after another;
    - `run_episode` one episode at a time (metrics_run before issue 12);
    - `metrics_run`, in lockstep (one call per step for every running episode), with the track
      cache empty (as a new worker process) and warm (every later submission of a course).
    Target: lockstep metrics_run >= 4x the plain loop (issue 12), <= 10 s (issue 3).
(b) How many of those episodes end differently in lockstep than one at a time: ONNX Runtime's
    batched matmuls sum in another order, so actions may differ in the last bits.
(c) a 10-car race of ONNX agents: target <= 2 s;
(d) saving that race's GIF: target <= 30 s.
(e) the same 100 episodes of exports fixed to batch size 1 (many students' files; a quarter of the
    deadline rush's), as evaluated before (row by row: a model call per running episode per step)
    and now (ONNX: the graph given a free batch dimension when it answers a batch as it answers
    each row; TorchScript: the rows in one no_grad and checked once).

Times are CPU time of this process (time.process_time): on a shared machine, the other
processes' time slices on this core are not counted.

The actor is `tests/toolkit_models.thesis_driver`: real 64-unit matmuls, wired to drive like
the heuristic so that episodes are full laps (a random actor would crash in a few steps and
flatter the figures).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from _league import plain_loop  # noqa: E402

TARGETS = {"metrics_run": 10.0, "race": 2.0, "gif": 30.0}  # seconds
SPEED_UP_TARGET = 4.0  # lockstep metrics_run against the plain loop


def pin_to_one_core() -> str:
    if hasattr(os, "sched_setaffinity"):
        core = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {core})
        return f"pinned to core {core}"
    return "not pinned (no sched_setaffinity here)"


def export_actors(folder: Path, count: int) -> list[Path]:
    from league.agents import export_onnx
    from tests.toolkit_models import thesis_driver

    # Different speed targets (0.20 ... 0.29) make a real race: the cars spread out.
    return [export_onnx(thesis_driver(seed=k, target_speed=0.20 + 0.01 * k), folder / f"actor_{k}.onnx")
            for k in range(count)]


def timed(label: str, work, target: float | None = None):
    start = time.process_time()
    result = work()
    seconds = time.process_time() - start
    verdict = "" if target is None else f"   (target <= {target:g} s: {'ok' if seconds <= target else 'OVER TARGET'})"
    print(f"{label:<58} {seconds:7.2f} s{verdict}")
    return result, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--out", type=Path, default=None, help="where to keep the GIF and replay (default: a temp dir)")
    args = parser.parse_args()

    import league
    from league.agents import load_agent
    from league.evaluation import episode_seeds, metrics_run, race, run_episode, save_replay
    from league.track import set_track_cache_size, track_cache_info
    from league.render import animate_replay

    print(f"toolkit benchmark, {pin_to_one_core()}")
    with tempfile.TemporaryDirectory() as scratch:
        out = args.out or Path(scratch)
        out.mkdir(parents=True, exist_ok=True)
        paths = export_actors(out, 10)
        agent = load_agent(paths[5])  # target speed 0.25, as the heuristic
        seeds = episode_seeds(0, args.episodes)

        n = args.episodes
        completed, plain = timed(f"(a) plain loop, gym.make + ONNX Runtime, {n} episodes",
                                 lambda: plain_loop(paths[5], seeds))
        env = league.MicroRacerEnv()
        alone, _ = timed("    run_episode, one episode at a time (before issue 12)",
                         lambda: [run_episode(env, agent, seed) for seed in seeds])
        set_track_cache_size(max(128, n))  # empties the cache: the first run draws every track
        result, cold = timed("    metrics_run in lockstep, empty track cache",
                             lambda: metrics_run(agent, episodes=n, seed=0), TARGETS["metrics_run"])
        _, warm = timed("    metrics_run in lockstep, tracks cached", lambda: metrics_run(agent, episodes=n, seed=0))
        steps = sum(e.steps for e in result.episodes)
        print(f"    {steps} steps, completed {result.completed}/{n} (plain loop: {completed}), "
              f"{track_cache_info().hits} cache hits; lockstep is {plain / cold:.1f}x the plain loop with an empty "
              f"cache, {plain / warm:.1f}x with cached tracks (target >= {SPEED_UP_TARGET:g}x)")

        changed = [(a, b) for a, b in zip(alone, result.episodes) if (a.outcome, a.steps) != (b.outcome, b.steps)]
        outcomes = sum(a.outcome != b.outcome for a, b in changed)
        drift = max(abs(a.episode_return - b.episode_return) for a, b in zip(alone, result.episodes))
        print(f"(b) lockstep against one at a time: {outcomes} of {n} episodes change outcome, {len(changed)} change "
              f"outcome or steps; largest return difference {drift:.2e}")

        agents = [load_agent(path, name=f"actor {k} (target {0.20 + 0.01 * k:.2f})") for k, path in enumerate(paths)]
        race_result, _ = timed("(c) 10-car race, ONNX agents", lambda: race(agents, seed=1), TARGETS["race"])
        replay_path = save_replay(race_result, out / "race.json")
        longest = max(len(car.x) - 1 for car in race_result.cars)
        finishers = sum(row["outcome"] == "finished" for row in race_result.classification)
        print(f"    {longest} steps, {finishers} finishers, replay {replay_path.stat().st_size / 1024:.0f} KiB")

        gif, _ = timed("(d) saving the race's GIF", lambda: animate_replay(race_result.replay, save=out / "race.gif"),
                       TARGETS["gif"])
        print(f"    {gif.stat().st_size / 1024:.0f} KiB" + (f", kept in {out}" if args.out else ""))
        fixed_batch_exports(out, seeds, timed)


def fixed_batch_exports(out: Path, seeds: list[int], timed) -> None:
    """(e): the row-by-row path (the loader's agent forced back to it) beside the loader's own."""
    import numpy as np

    from league.agents import Agent, OnnxAgent, TorchAgent, _onnx_session, import_onnxruntime, load_agent
    from league.evaluation import metrics_run
    from tests.server.model_factory import onnx_fixed_batch, torchscript_fixed_batch
    from tests.toolkit_models import thesis_driver

    n = len(seeds)
    onnx_file = onnx_fixed_batch(thesis_driver(target_speed=0.25), out / "fixed.onnx")
    as_exported = OnnxAgent(_onnx_session(import_onnxruntime(), onnx_file), 5, "row by row", fixed_batch=True, rank=2,
                            input_dtype=np.float32)
    _, before = timed(f"(e) ONNX fixed to batch 1, {n} episodes: row by row (before)",
                      lambda: metrics_run(as_exported, episodes=n, seed=0))
    agent = load_agent(onnx_file)
    _, after = timed(f"    the loader's agent ({'row by row' if agent.fixed_batch else 'free batch'})",
                     lambda: metrics_run(agent, episodes=n, seed=0))
    print(f"    {before / after:.1f}x")
    ts_file = torchscript_fixed_batch(thesis_driver(target_speed=0.25), out / "fixed.pt")
    agent = load_agent(ts_file)

    class EachRowOnItsOwn(TorchAgent):
        _act_rows = Agent._act_rows  # the generic path: a no_grad and a check per row

    each_row = EachRowOnItsOwn(agent._module, 5, "each row on its own")
    each_row.fixed_batch = True
    _, before = timed("    TorchScript fixed to batch 1: each row checked on its own (before)",
                      lambda: metrics_run(each_row, episodes=n, seed=0))
    _, after = timed("    the rows in one no_grad, checked once", lambda: metrics_run(agent, episodes=n, seed=0))
    print(f"    {before / after:.1f}x")


if __name__ == "__main__":
    main()
