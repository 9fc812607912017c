"""Benchmark of the student toolkit (issue 3's performance targets), on one core.

    python benchmarks/bench_toolkit.py [--episodes 100] [--out DIR]

(a) metrics_run of a thesis-size actor (5 -> 64 -> 64 -> 2, tanh) exported to ONNX, 100
    episodes, every option on: target <= 10 s;
(b) a 10-car race of ONNX agents: target <= 2 s;
(c) saving that race's GIF: target <= 30 s.

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

TARGETS = {"metrics_run": 10.0, "race": 2.0, "gif": 30.0}  # seconds


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


def timed(label: str, target: float, work):
    start = time.perf_counter()
    result = work()
    seconds = time.perf_counter() - start
    verdict = "ok" if seconds <= target else "OVER TARGET"
    print(f"{label:<48} {seconds:7.2f} s   (target <= {target:g} s: {verdict})")
    return result, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--out", type=Path, default=None, help="where to keep the GIF and replay (default: a temp dir)")
    args = parser.parse_args()

    from league.agents import load_agent
    from league.evaluation import metrics_run, race, save_replay
    from league.render import animate_replay

    print(f"toolkit benchmark, {pin_to_one_core()}")
    with tempfile.TemporaryDirectory() as scratch:
        out = args.out or Path(scratch)
        out.mkdir(parents=True, exist_ok=True)
        paths = export_actors(out, 10)
        agent = load_agent(paths[5])  # target speed 0.25, as the heuristic

        result, seconds = timed(f"(a) metrics_run, {args.episodes} episodes, ONNX actor", TARGETS["metrics_run"],
                                lambda: metrics_run(agent, episodes=args.episodes, seed=0))
        steps = sum(e.steps for e in result.episodes)
        print(f"    {steps} steps, {seconds / steps * 1e6:.1f} us per step (env + lidar + ONNX), "
              f"completed {result.completed}/{result.episodes_total}, mean speed {result.mean_speed:.3f}")

        agents = [load_agent(path, name=f"actor {k} (target {0.20 + 0.01 * k:.2f})") for k, path in enumerate(paths)]
        race_result, _ = timed("(b) 10-car race, ONNX agents", TARGETS["race"], lambda: race(agents, seed=1))
        replay_path = save_replay(race_result, out / "race.json")
        longest = max(len(car.x) - 1 for car in race_result.cars)
        finishers = sum(row["outcome"] == "finished" for row in race_result.classification)
        print(f"    {longest} steps, {finishers} finishers, replay {replay_path.stat().st_size / 1024:.0f} KiB")

        gif, _ = timed("(c) saving the race's GIF", TARGETS["gif"], lambda: animate_replay(race_result.replay, save=out / "race.gif"))
        print(f"    {gif.stat().st_size / 1024:.0f} KiB" + (f", kept in {out}" if args.out else ""))


if __name__ == "__main__":
    main()
