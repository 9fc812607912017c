"""Simulator speed: reset, one-car step, lidar, PettingZoo step with 64 cars, the batched interface.

    python benchmarks/bench_simulator.py [--quick]

Prints medians over many calls (one process, one thread). Cars are driven by the SPEC's
heuristic driver, computed for all cars at once in numpy, so they stay on the road; only the
step calls are timed, never the resets.
Targets (issue 2): reset <= 3 ms, step <= 5 us, lidar <= 1.5 us,
PettingZoo 64 cars >= 250k car-steps/s, batched >= 1M car-steps/s.
"""
from __future__ import annotations

import argparse
import time
import timeit

import gymnasium as gym
import numpy as np

import league
from league import lidar


def heuristic(obs: np.ndarray) -> np.ndarray:
    """SPEC's driver for a batch of compact observations: steer to the free direction, hold ~0.25."""
    actions = np.empty((len(obs), 2), dtype=np.float32)
    actions[:, 0] = np.where(obs[:, 4] < 0.25, 0.5, -0.2)
    actions[:, 1] = np.clip(-obs[:, 0] / (np.pi / 6), -1, 1)
    return actions


def median_us(samples) -> float:
    return float(np.median(samples) * 1e6)


def bench_reset(n: int) -> float:
    env = league.MicroRacerEnv()
    env.reset(seed=0)
    samples = []
    for _ in range(n):
        t0 = time.perf_counter()
        env.reset()
        samples.append(time.perf_counter() - t0)
    return median_us(samples)


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


def bench_parallel(n_cars: int, seconds: float, batched: bool) -> float:
    """Car-steps per second of running cars, timing only the step calls."""
    penv = league.parallel_env(n_cars=n_cars)
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
                if not (penv.cars.outcome == 0).any():
                    penv.agents = []
            else:
                action_dict = {a: actions[int(a[4:])] for a in penv.agents}
                t0 = time.perf_counter()
                observations, _, _, _, _ = penv.step(action_dict)
                elapsed += time.perf_counter() - t0
                for a, o in observations.items():
                    obs[int(a[4:])] = o
            car_steps += running
    return car_steps / elapsed


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    args = parser.parse_args()
    scale = 0.1 if args.quick else 1.0
    rows = [
        ("reset, new random track, all options on", bench_reset(int(300 * scale)), "us", "<= 3000"),
        ("MicroRacerEnv.step, one car", bench_step(league.MicroRacerEnv(), int(20000 * scale)), "us", "<= 5"),
        ("gym.make(...).step (with Gymnasium's wrappers)", bench_step(gym.make("league/MicroRacer-v0"), int(20000 * scale)), "us", ""),
        ("lidar of one car (19 rays)", bench_lidar(int(100000 * scale)), "us", "<= 1.5"),
        ("PettingZoo step, 64 cars", bench_parallel(64, 3 * scale, batched=False), "car-steps/s", ">= 250000"),
        ("batched step_arrays, 64 cars", bench_parallel(64, 3 * scale, batched=True), "car-steps/s", ">= 1000000"),
    ]
    print(f"{'measure':<50} {'median':>12}  {'unit':<12} target")
    for name, value, unit, target in rows:
        print(f"{name:<50} {value:>12,.1f}  {unit:<12} {target}")


if __name__ == "__main__":
    main()
