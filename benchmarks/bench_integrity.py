"""Benchmark of the integrity report, and the distances its tolerance sits between.

    python benchmarks/bench_integrity.py [--submissions 600 3000] [--repeats 3]

(a) Distances on the probe set (league.validation.probes), the agents run in this process: one
    network exported to ONNX and to TorchScript; thesis-size drivers that hold different speeds
    (league.testing.thesis_driver); the bundled baselines, pairwise. The tolerance
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
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from _league import run_script
from league.agents import export_onnx, export_torchscript, load_agent
from league.server.config import BUNDLED_BASELINES
from league.server.integrity import Candidate, integrity_report
from league.testing import thesis_driver
from league.validation.probes import PROBES, probe_actions_bytes, probe_key, probe_observations

SPEEDS = (0.21, 0.25, 0.29, 0.37)  # the drivers' target speeds in (a)


@dataclass
class Distances:
    """(a) max-abs distances of actions on the probe set."""

    formats: dict[float, float]  # a driver's target speed -> its ONNX export against its TorchScript one
    drivers: dict[tuple[float, float], float]  # two drivers' target speeds -> their distance
    baselines: list[float]  # the bundled baselines, every pair


@dataclass
class ReportTime:
    """(b) the report over `submissions` submissions, beside the path it replaces."""

    submissions: int
    report_s: float  # median of `repeats`
    repeats: int
    groups: int
    every_pair_s: float


def distances() -> Distances:
    obs5 = probe_observations(5)
    outputs, formats = {}, {}
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        for speed in SPEEDS:
            net = thesis_driver(seed=1, target_speed=speed)
            outputs[speed] = load_agent(export_onnx(net, work / f"{speed}.onnx"))(obs5)
            twice = load_agent(export_torchscript(net, work / f"{speed}.pt"))(obs5)
            formats[speed] = float(np.abs(outputs[speed] - twice).max())
    drivers = {(a, b): float(np.abs(outputs[a] - outputs[b]).max()) for a, b in itertools.combinations(outputs, 2)}
    baselines = {p.stem: load_agent(p)(probe_observations(20)) for p in sorted(BUNDLED_BASELINES.glob("*.onnx"))}
    pairs = [float(np.abs(baselines[a] - baselines[b]).max()) for a, b in itertools.combinations(baselines, 2)]
    return Distances(formats=formats, drivers=drivers, baselines=pairs)


def report_distances(found: Distances) -> None:
    for speed, distance in found.formats.items():
        print(f"(a) driver {speed}: ONNX vs TorchScript  {distance:.1e}")
    for (a, b), distance in found.drivers.items():
        print(f"(a) drivers {a} vs {b}:  {distance:.3f}")
    pairs = found.baselines
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


def report_time(submissions: int, repeats: int, rng: np.random.Generator) -> ReportTime:
    candidates = course(submissions, rng)
    seconds, report = timed(lambda: integrity_report(candidates, bundled={}, tolerance=1e-3), repeats)
    replaced, _ = timed(lambda: every_pair(candidates, 1e-3), 1)
    return ReportTime(submissions=submissions, report_s=seconds, repeats=repeats, groups=len(report.groups),
                      every_pair_s=replaced)


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--submissions", type=int, nargs="+", default=[600, 3000])
    parser.add_argument("--repeats", type=int, default=3)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    report_distances(distances())
    rng = np.random.default_rng(0)
    for n in args.submissions:
        t = report_time(n, args.repeats, rng)
        print(f"(b) {t.submissions} submissions: report {t.report_s * 1000:.0f} ms (median of {t.repeats}), "
              f"{t.groups} groups; every pair's distance alone {t.every_pair_s * 1000:.0f} ms")
    return 0


if __name__ == "__main__":
    run_script(main)
