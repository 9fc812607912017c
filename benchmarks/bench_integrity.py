"""Benchmark of the integrity report, and the distances its tolerance sits between.

    python benchmarks/bench_integrity.py [--submissions 600 3000] [--repeats 3]

(a) Distances on the probe set (league.validation.probes), the agents run in this process: one
    network exported to ONNX and to TorchScript; thesis-size drivers that hold different speeds
    (tests/toolkit_models.thesis_driver); the bundled baselines, pairwise. The tolerance
    (integrity_tolerance, 1e-3) must sit far above the first and far below the others.
(b) league.server.integrity.integrity_report over N submissions of a course (N/3 students, random
    actions, 5 % of them copies of another student's file, 5 % another student's actions plus
    rounding noise): the wall time of the report (close_pairs: the pairs whose actions' means
    are within the tolerance, then their max-abs distances, vectorised), beside the path it
    replaces: every pair's max-abs distance, vectorised 64 rows x N at a time.
"""
from __future__ import annotations

import argparse
import itertools
import statistics
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from league.agents import export_onnx, export_torchscript, load_agent
from league.server.config import BUNDLED_BASELINES
from league.server.integrity import Candidate, integrity_report
from league.validation.probes import PROBES, probe_actions_bytes, probe_key, probe_observations
from tests.toolkit_models import thesis_driver


def distances() -> None:
    obs5, work = probe_observations(5), Path(tempfile.mkdtemp())
    drivers = {}
    for speed in (0.21, 0.25, 0.29, 0.37):
        net = thesis_driver(seed=1, target_speed=speed)
        drivers[speed] = load_agent(export_onnx(net, work / f"{speed}.onnx"))(obs5)
        twice = load_agent(export_torchscript(net, work / f"{speed}.pt"))(obs5)
        print(f"(a) driver {speed}: ONNX vs TorchScript  {np.abs(drivers[speed] - twice).max():.1e}")
    for a, b in itertools.combinations(drivers, 2):
        print(f"(a) drivers {a} vs {b}:  {np.abs(drivers[a] - drivers[b]).max():.3f}")
    baselines = {p.stem: load_agent(p)(probe_observations(20)) for p in sorted(BUNDLED_BASELINES.glob("*.onnx"))}
    pairs = [np.abs(baselines[a] - baselines[b]).max() for a, b in itertools.combinations(baselines, 2)]
    print(f"(a) bundled baselines pairwise ({len(pairs)} pairs): {min(pairs):.3f} to {max(pairs):.3f}")


def course(n: int, rng: np.random.Generator) -> list[Candidate]:
    key, when, out = probe_key(5), datetime(2026, 11, 25, tzinfo=timezone.utc), []
    for i in range(n):
        owner, sha, acts = i % (n // 3), f"{i:064x}", rng.uniform(-1, 1, (PROBES, 2))
        if i > 10 and rng.random() < 0.05:
            sha = out[int(rng.integers(i))].sha256  # a copied file
        elif i > 10 and rng.random() < 0.05:
            acts = np.frombuffer(out[int(rng.integers(i))].probe_actions, np.float32).reshape(PROBES, 2) + 1e-6
        out.append(Candidate(i, f"agent {i}", owner, f"student {owner}", False, "onnx", sha, 5, key,
                             probe_actions_bytes(acts), when))
    return out


def timed(function, repeats: int) -> tuple[float, object]:
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def every_pair(submissions: list[Candidate], tolerance: float) -> int:
    """The replaced path: the max-abs distance of every pair, 64 rows x n at a time."""
    matrix = np.stack([np.frombuffer(s.probe_actions, np.float32) for s in submissions])
    found = 0
    for start in range(0, len(matrix), 64):
        block = np.abs(matrix[start:start + 64, None, :] - matrix[None, :, :]).max(axis=2)
        found += int(np.triu(block <= tolerance, k=start + 1).sum())
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--submissions", type=int, nargs="+", default=[600, 3000])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    distances()
    rng = np.random.default_rng(0)
    for n in args.submissions:
        submissions = course(n, rng)
        seconds, report = timed(lambda: integrity_report(submissions, bundled={}, tolerance=1e-3), args.repeats)  # noqa: B023 - called in this iteration
        replaced, _ = timed(lambda: every_pair(submissions, 1e-3), 1)  # noqa: B023 - called in this iteration
        print(f"(b) {n} submissions: report {seconds * 1000:.0f} ms (median of {args.repeats}), "
              f"{len(report.groups)} groups; every pair's distance alone {replaced * 1000:.0f} ms")


if __name__ == "__main__":
    main()
