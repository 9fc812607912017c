"""Where a SAC training iteration spends its time (one thread, as `league train`); with --runs, the
final and the best actor of finished training runs side by side.

    python benchmarks/bench_baselines.py [--updates 3000] [--envs 1] [--warmup 2000]
    python benchmarks/bench_baselines.py --runs runs        # after the training commands of docs/BASELINES.md

Times each part of the off-policy loop (league.baselines.common.off_policy) with SAC's learner
on its own: acting, stepping the car, storing, sampling, the critic update, the actor and temperature update, and prints
milliseconds per iteration and the share of each. With --runs, exports each run's final actor
(what `league train` leaves at its end) and its best-validated one to ONNX and evaluates both as
`league evaluate AGENT --episodes 100 --seed 0` does, per method and seed, beside the thesis' mean.
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from league.baselines import sac
from league.baselines.common.buffers import ReplayBuffer
from league.baselines.common.cars import Cars
from league.baselines.common.seeding import seed_everything

PARTS = ("act", "env step", "store", "sample", "critic update", "actor + temperature", "target update")


@dataclass
class LoopFigures:
    iterations: int
    threads: int
    total_s: float
    parts_s: dict[str, float]  # each part of the loop, summed over the iterations

    @property
    def ms_per_iteration(self) -> float:
        return 1e3 * self.total_s / self.iterations


def measure(updates: int, envs: int = 1, warmup: int = 2000) -> LoopFigures:
    """`updates` iterations of SAC's loop after `warmup` random steps (data, and fitted observation statistics)."""
    args = sac.Args()
    seed_everything(0)
    cars = Cars(envs, seed=0, neutral_prob=args.neutral_prob, observation=args.observation)
    agent = sac.SoftActorCritic(cars.obs_dim, args)
    rb = ReplayBuffer(args.buffer_size, cars.obs_dim, 2, seed=0)
    obs = cars.reset()
    for _ in range(warmup):
        actions = np.random.uniform(-1, 1, (cars.n, 2)).astype(np.float32)
        step = cars.step(actions)
        rb.add(obs, actions, step.rewards, step.next_obs, step.terminated & ~step.finished)
        obs = cars.obs.copy()
    agent.fit_normalizers(rb.observations[:rb.size])
    parts = dict.fromkeys(PARTS, 0.0)

    def clock(name, fn, *a):
        start = time.perf_counter()
        out = fn(*a)
        parts[name] += time.perf_counter() - start
        return out

    total = time.perf_counter()
    for _ in range(updates):
        actions = clock("act", agent.act, obs)
        step = clock("env step", cars.step, actions)
        clock("store", rb.add, obs, actions, step.rewards, step.next_obs, step.terminated & ~step.finished)
        obs = cars.obs.copy()
        data = clock("sample", rb.sample, args.batch_size)
        clock("critic update", agent.update_critics, data)
        clock("actor + temperature", agent.update_actor, data)
        clock("target update", agent.after_update)  # the loop's hook: SAC's Polyak step
    return LoopFigures(iterations=updates, threads=torch.get_num_threads(), total_s=time.perf_counter() - total,
                       parts_s=parts)


def report(figures: LoopFigures) -> None:
    f = figures
    print(f"SAC, {f.iterations} iterations, {f.threads} thread(s): {f.ms_per_iteration:.2f} ms per iteration "
          f"-> 50 000 iterations in {50_000 * f.total_s / f.iterations / 60:.1f} min (without evaluations)")
    for name, seconds in f.parts_s.items():
        print(f"  {name:<20} {1e3 * seconds / f.iterations:6.3f} ms  {100 * seconds / f.total_s:5.1f} %")


@dataclass
class ActorFigures:
    algorithm: str
    seed: int
    final: dict  # `league evaluate --episodes 100 --seed 0` of the actor at the end of the run
    best: dict  # the same of the actor of its best periodic validation


def measure_actors(root: Path) -> list[ActorFigures]:
    """Final and best actor of every finished run under `root` (see baselines_report.py)."""
    from baselines_report import evaluate_run, find_runs

    return [ActorFigures(algorithm, json.loads((folder / "summary.json").read_text())["seed"],
                         evaluate_run(folder, "final"), evaluate_run(folder, "best"))
            for algorithm, folders in find_runs(root).items() for folder in folders]


def report_actors(rows: list[ActorFigures]) -> None:
    from baselines_report import LABELS, THESIS

    print("completed / 100 (mean speed), `league evaluate AGENT --episodes 100 --seed 0`, ONNX")
    print(f"{'method':<7} {'seed':>4}  {'final':>12}  {'best':>12}")
    for algorithm in dict.fromkeys(r.algorithm for r in rows):
        mine = [r for r in rows if r.algorithm == algorithm]
        for r in mine:
            print(f"{LABELS[algorithm]:<7} {r.seed:>4}  {r.final['completed']:>4} ({r.final['mean_speed']:.3f})  "
                  f"{r.best['completed']:>4} ({r.best['mean_speed']:.3f})")
        final, best = (np.mean([getattr(r, w)["completed"] for r in mine]) for w in ("final", "best"))
        print(f"{LABELS[algorithm]:<7} mean  {final:>4.0f}          {best:>4.0f}          thesis mean "
              f"{THESIS[algorithm][1]}: final {'>=' if final >= THESIS[algorithm][1] else '<'} thesis")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--updates", type=int, default=3000)
    parser.add_argument("--envs", type=int, default=1)
    parser.add_argument("--warmup", type=int, default=2000, help="random steps stored before the timed loop")
    parser.add_argument("--runs", type=Path, help="a folder of finished runs: their final and best actors instead")
    options = parser.parse_args(argv)
    if options.runs:
        report_actors(measure_actors(options.runs))
    else:
        report(measure(options.updates, options.envs, options.warmup))


if __name__ == "__main__":
    main()
