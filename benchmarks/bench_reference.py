"""This simulator beside the original MicroRacer, timed in the same process: reset and step.

    git clone https://github.com/asperti/MicroRacer /tmp/microracer-ref
    python benchmarks/bench_reference.py --reference /tmp/microracer-ref [--rounds 3]

The original is imported from its own checkout, unchanged (its `tracks.py` compiles its
`lidar.pyx` with pyximport, here into a temporary directory); nothing of it is copied. Both
run with every option on, both cars driven by SPEC's heuristic driver (computed outside the
timing); only the reset and step calls are timed, with the original's prints sent to /dev/null.
The two take turns (a reset each, then 100 steps each), so a change of the machine's speed
hits both alike; each round prints its medians and their ratio, the last lines the medians over
all samples.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import league
from league.agents import heuristic_actions

RESET_RATIO_TARGET = 300  # a reset with a new track against the original's (issue 33)


def import_original(checkout: Path):
    """The original's `tracks` module, its lidar compiled by its own pyximport call in a temporary cwd."""
    if not (checkout / "tracks.py").exists():
        sys.exit(f"{checkout} has no tracks.py: pass a checkout of https://github.com/asperti/MicroRacer")
    sys.path.insert(0, str(checkout))
    previous = os.getcwd()
    os.chdir(tempfile.mkdtemp(prefix="microracer-ref-build-"))  # its .pyxbld directory goes here
    try:
        with open(os.devnull, "w") as quiet, contextlib.redirect_stdout(quiet):
            import tracks
    finally:
        os.chdir(previous)
    return tracks


class Original:
    """The original Racer behind the same two calls as ours."""

    def __init__(self, tracks):
        self.racer = tracks.Racer()

    def reset(self):
        return np.asarray(self.racer.reset(), dtype=np.float32)

    def step(self, action):
        state, _, done = self.racer.step(action)
        return np.asarray(state, dtype=np.float32), done


class Ours:
    def __init__(self):
        self.env = league.MicroRacerEnv()
        self.env.reset(seed=0)

    def reset(self):
        return self.env.reset()[0]

    def step(self, action):
        obs, _, terminated, truncated, _ = self.env.step(action)
        return obs, terminated or truncated


class Driver:
    """Steps a simulator with SPEC's heuristic driver, starting a new episode (untimed) when one ends."""

    def __init__(self, sim):
        self.sim, self.obs = sim, sim.reset()

    def timed_steps(self, n: int) -> list[float]:
        samples = []
        for _ in range(n):
            action = heuristic_actions(self.obs[None])[0]
            t0 = time.perf_counter()
            self.obs, done = self.sim.step(action)
            samples.append(time.perf_counter() - t0)
            if done:
                self.obs = self.sim.reset()
        return samples


def timed_reset(sim) -> float:
    t0 = time.perf_counter()
    sim.reset()
    return time.perf_counter() - t0


def measure(tracks, resets: int, steps: int, block: int = 100) -> dict:
    """Samples of both simulators, taken in turn (a reset each, then `block` steps each), so a
    change of the machine's speed during the run hits both alike."""
    sims = {"original": Original(tracks), "league": Ours()}
    drivers = {name: Driver(sim) for name, sim in sims.items()}
    samples = {name: {"reset": [], "step": []} for name in sims}
    for _ in range(resets):
        for name, sim in sims.items():
            samples[name]["reset"].append(timed_reset(sim))
    for _ in range(steps // block):
        for name, driver in drivers.items():
            samples[name]["step"] += driver.timed_steps(block)
    return samples


def report(label: str, original: dict, ours: dict) -> None:
    for measure_, unit, scale in (("reset", "ms", 1e3), ("step", "us", 1e6)):
        a, b = np.median(original[measure_]) * scale, np.median(ours[measure_]) * scale
        target = f"   (target >= {RESET_RATIO_TARGET:g}x)" if measure_ == "reset" else ""
        print(f"{label:<10} {measure_:<6} original {a:10.2f} {unit}   league {b:8.3f} {unit}   "
              f"ratio {a / b:6.1f}x{target}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reference", type=Path, required=True, help="a checkout of asperti/MicroRacer")
    parser.add_argument("--rounds", type=int, default=3, help="rounds, each printed")
    parser.add_argument("--resets", type=int, default=30, help="timed resets of each simulator per round")
    parser.add_argument("--steps", type=int, default=5000, help="timed steps of each simulator per round")
    args = parser.parse_args()
    tracks = import_original(args.reference.resolve())
    np.random.seed(0)  # the original draws its tracks from NumPy's global generator
    totals = {name: {"reset": [], "step": []} for name in ("original", "league")}
    with open(os.devnull, "w") as quiet:
        for round_ in range(1, args.rounds + 1):
            with contextlib.redirect_stdout(quiet):  # the original prints at every reset and crash
                samples = measure(tracks, args.resets, args.steps)
            report(f"round {round_}", samples["original"], samples["league"])
            for name in totals:
                for key, values in samples[name].items():
                    totals[name][key] += values
    report("all", totals["original"], totals["league"])


if __name__ == "__main__":
    main()
