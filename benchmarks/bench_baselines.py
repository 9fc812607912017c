"""Where a SAC training iteration spends its time (one thread, as `league train`).

    python benchmarks/bench_baselines.py [--updates 3000]

Times each part of the loop of `league.baselines.sac.train` on its own: acting, stepping the
car, storing, sampling, the critic update, the actor and temperature update, and prints
milliseconds per iteration and the share of each.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from league.baselines import sac
from league.baselines.common.buffers import ReplayBuffer
from league.baselines.common.cars import Cars
from league.baselines.common.seeding import seed_everything


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--updates", type=int, default=3000)
    parser.add_argument("--envs", type=int, default=1)
    options = parser.parse_args()
    n = options.updates
    args = sac.Args()
    seed_everything(0)
    cars = Cars(options.envs, seed=0, neutral_prob=args.neutral_prob, observation=args.observation)
    agent = sac.SoftActorCritic(cars.obs_dim, args)
    rb = ReplayBuffer(args.buffer_size, cars.obs_dim, 2, seed=0)
    obs = cars.reset()
    for _ in range(2000):  # some data, and fitted observation statistics
        actions = np.random.uniform(-1, 1, (cars.n, 2)).astype(np.float32)
        step = cars.step(actions)
        rb.add(obs, actions, step.rewards, step.next_obs, step.terminated & ~step.finished)
        obs = cars.obs.copy()
    agent.fit_normalizers(rb.observations[:rb.size])
    parts = {"act": 0.0, "env step": 0.0, "store": 0.0, "sample": 0.0, "critic update": 0.0,
             "actor + temperature": 0.0, "target update": 0.0}

    def clock(name, fn, *a):
        start = time.perf_counter()
        out = fn(*a)
        parts[name] += time.perf_counter() - start
        return out

    total = time.perf_counter()
    for _ in range(n):
        actions = clock("act", agent.act, obs)
        step = clock("env step", cars.step, actions)
        clock("store", rb.add, obs, actions, step.rewards, step.next_obs, step.terminated & ~step.finished)
        obs = cars.obs.copy()
        data = clock("sample", rb.sample, args.batch_size)
        clock("critic update", agent.update_critics, data)
        clock("actor + temperature", agent.update_actor, data)
        clock("target update", agent.update_targets)
    total = time.perf_counter() - total
    print(f"SAC, {n} iterations, {torch.get_num_threads()} thread(s): {1e3 * total / n:.2f} ms per iteration "
          f"-> 50 000 iterations in {50_000 * total / n / 60:.1f} min (without evaluations)")
    for name, seconds in parts.items():
        print(f"  {name:<20} {1e3 * seconds / n:6.3f} ms  {100 * seconds / total:5.1f} %")


if __name__ == "__main__":
    main()
