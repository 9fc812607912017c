"""Benchmark of the integrity report, and the distances its tolerance sits between.

    python benchmarks/bench_integrity.py [--submissions 200 600 3000] [--repeats 3]

(a) Behaviour distances (league.server.course.integrity.behaviour_distances) on the public probe set and
    on a secret set (league.validation.probes.secret_probe_observations, drawn on private tracks),
    the agents run in this process: one network exported to ONNX and to TorchScript; thesis-size
    drivers that steer alike and hold different speeds (league.testing.thesis_driver); the bundled
    baselines, pairwise; disguised copies of each bundled baseline (league.testing: last layer x
    1.03, outputs x 0.98, outputs x 0.9 + 0.05, weights + N(0, 1e-6), an extra identity layer, a
    TorchScript re-export, a probe-aware copy that answers the public set otherwise), and beside
    them the max-abs difference the report used before (whose tolerance was 1e-3). The tolerance
    (integrity_tolerance) must sit far above the copies and far below the distinct agents.
(b) league.server.course.integrity.integrity_report over N submissions of a course, each with actions
    on the public set (64 probes) and on its assignment's secret set (192) (N/3 students, random actions, 5 % of
    them copies of another student's file, 5 % another student's actions rescaled, offset and
    noisy): the wall time of the report (the behaviour distance matrix, 256 rows at a time, by
    matrix products), beside the report it replaces (max-abs distances on the public set only,
    comparing only the pairs whose mean actions are within its tolerance).
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
from league.server.core.config import BUNDLED_BASELINES, Settings
from league.server.course.integrity import Candidate, behaviour_distances, integrity_report
from league.testing import disguised_copies, thesis_driver
from league.validation.probes import (
    PROBES, SECRET_PROBES, observations_key, probe_actions_bytes, probe_actions_from_bytes, probe_key,
    probe_observations, secret_probe_observations,
)

SPEEDS = (0.21, 0.25, 0.29, 0.37)  # the drivers' target speeds in (a)
PRIVATE = {"seed": 2_718_281_828, "episodes": 20, "env_options": {}}  # an assignment's private tracks in (a)
OLD_TOLERANCE = 1e-3  # the max-abs report's
VARIANTS = disguised_copies()


@dataclass
class Distances:
    """(a) behaviour distances on the public set / the secret set; the copies' also as max-abs."""

    formats: dict[float, tuple[float, float]]  # a driver's target speed -> its ONNX export against its TorchScript one
    drivers: dict[tuple[float, float], tuple[float, float]]  # two drivers' target speeds -> their distances
    baselines: list[tuple[float, float]]  # the bundled baselines, every pair
    copies: dict[str, list[tuple[float, float, float]]]  # variant -> (public, secret, old max-abs), a baseline each


@dataclass
class ReportTime:
    """(b) the report over `submissions` submissions, beside the one it replaces."""

    submissions: int
    report_s: float  # wall time, median of `repeats`
    report_cpu_s: float  # this process's CPU time, median of `repeats` (the machine may be shared)
    repeats: int
    groups: int
    old_report_s: float


def both(agent_a, agent_b, obs_dim: int) -> tuple[float, float]:
    """Behaviour distances of two agents on the public set and on the secret one."""
    sets = (probe_observations(obs_dim), secret_probe_observations(PRIVATE, obs_dim))
    return tuple(float(behaviour_distances(agent_a(obs)[None], agent_b(obs)[None])[0, 0]) for obs in sets)


def distances() -> Distances:
    formats, drivers = {}, {}
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        onnx_agents = {}
        for speed in SPEEDS:
            net = thesis_driver(seed=1, target_speed=speed)
            onnx_agents[speed] = load_agent(export_onnx(net, work / f"{speed}.onnx"))
            formats[speed] = both(onnx_agents[speed], load_agent(export_torchscript(net, work / f"{speed}.pt")), 5)
        for a, b in itertools.combinations(SPEEDS, 2):
            drivers[(a, b)] = both(onnx_agents[a], onnx_agents[b], 5)
        baselines = {p.stem: load_agent(p) for p in sorted(BUNDLED_BASELINES.glob("*.onnx"))}
        pairs = [both(baselines[a], baselines[b], 20) for a, b in itertools.combinations(baselines, 2)]
        copies: dict[str, list[tuple[float, float, float]]] = {name: [] for name in VARIANTS}
        public = probe_observations(20)
        for stem, original in baselines.items():
            for n, (name, make) in enumerate(VARIANTS.items()):
                copy = load_agent(make(BUNDLED_BASELINES / f"{stem}.onnx", work / f"{stem}-{n}"))
                copies[name].append((*both(original, copy, 20), float(np.abs(original(public) - copy(public)).max())))
    return Distances(formats=formats, drivers=drivers, baselines=pairs, copies=copies)


def span(values) -> str:
    values = list(values)
    return f"{min(values):.1e} to {max(values):.1e}"


def report_distances(found: Distances) -> None:
    print(f"(a) behaviour distances, public set / secret set (tolerance {Settings().integrity_tolerance}):")
    for speed, (public, secret) in found.formats.items():
        print(f"    driver {speed}: ONNX vs TorchScript  {public:.1e} / {secret:.1e}")
    for (a, b), (public, secret) in found.drivers.items():
        print(f"    drivers {a} vs {b}:  {public:.3f} / {secret:.3f}")
    pairs = found.baselines
    print(f"    bundled baselines pairwise ({len(pairs)} pairs): {min(min(p) for p in pairs):.3f} to "
          f"{max(max(p) for p in pairs):.3f}")
    for name, values in found.copies.items():
        print(f"    copies of the {len(values)} baselines, {name}: public {span(v[0] for v in values)}, secret "
              f"{span(v[1] for v in values)}; old max-abs on the public set {span(v[2] for v in values)}")


def course(n: int, rng: np.random.Generator) -> list[Candidate]:
    """n submissions with actions on the public set and on one secret set (keyed here by any values)."""
    public, secret = probe_key(5), observations_key(np.full((PROBES, 5), 0.5, np.float32))
    when, out = datetime(2026, 11, 25, tzinfo=timezone.utc), []
    for i in range(n):
        owner, sha = i % (n // 3), f"{i:064x}"
        acts = [rng.uniform(-1, 1, (PROBES, 2)), rng.uniform(-1, 1, (SECRET_PROBES, 2))]
        if i > 10 and rng.random() < 0.05:
            sha = out[int(rng.integers(i))].sha256  # a copied file
        elif i > 10 and rng.random() < 0.05:
            source = out[int(rng.integers(i))]
            acts = [0.97 * probe_actions_from_bytes(copied) + 0.02 + rng.normal(0, 1e-4, (len(copied) // 8, 2))
                    for copied in (source.probe_actions, source.secret[0][1])]  # rescaled, offset, noisy
        out.append(Candidate(i, f"agent {i}", owner, f"student {owner}", False, "onnx", sha, 5, public,
                             probe_actions_bytes(acts[0]), when, secret=((secret, probe_actions_bytes(acts[1])),),
                             secret_keys=(secret,)))
    return out


def timed(function, repeats: int) -> tuple[float, object, float]:
    """Median wall time, the last result, median CPU time."""
    times, cpu, result = [], [], None
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = function()
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return statistics.median(times), result, statistics.median(cpu)


def old_close_pairs(matrix: np.ndarray, tolerance: float) -> list[tuple[int, int]]:
    """The replaced report's comparison: max-abs within `tolerance`, only for rows whose means are
    within it (sorted by mean, searchsorted), 8192 pairs at a time."""
    rows = np.asarray(matrix, dtype=np.float64)
    means = rows.mean(axis=1)
    order = np.argsort(means, kind="stable")
    rows, means = rows[order], means[order]
    ends = np.searchsorted(means, means + tolerance * (1 + 1e-9), side="right")
    counts = ends - np.arange(len(rows)) - 1
    first = np.repeat(np.arange(len(rows)), counts)
    second = first + 1 + np.arange(len(first)) - np.repeat(np.cumsum(counts) - counts, counts)
    close = []
    for start in range(0, len(first), 8192):
        i, j = first[start:start + 8192], second[start:start + 8192]
        near = np.abs(rows[i] - rows[j]).max(axis=1) <= tolerance
        close += zip(order[i[near]].tolist(), order[j[near]].tolist())
    return close


def old_report(submissions: list[Candidate]) -> int:
    """The replaced report's work: the public set's max-abs pairs (grouping as today)."""
    matrix = np.stack([np.frombuffer(s.probe_actions, np.float32) for s in submissions])
    return len(old_close_pairs(matrix, OLD_TOLERANCE))


def report_time(submissions: int, repeats: int, rng: np.random.Generator) -> ReportTime:
    candidates = course(submissions, rng)
    tolerance = Settings().integrity_tolerance
    seconds, report, cpu = timed(lambda: integrity_report(candidates, bundled={}, tolerance=tolerance), repeats)
    replaced, _, _ = timed(lambda: old_report(candidates), repeats)
    return ReportTime(submissions=submissions, report_s=seconds, report_cpu_s=cpu, repeats=repeats,
                      groups=len(report.groups), old_report_s=replaced)


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--submissions", type=int, nargs="+", default=[200, 600, 3000])
    parser.add_argument("--repeats", type=int, default=3)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    report_distances(distances())
    rng = np.random.default_rng(0)
    for n in args.submissions:
        t = report_time(n, args.repeats, rng)
        print(f"(b) {t.submissions} submissions, 2 probe sets each: report {t.report_s * 1000:.0f} ms wall, "
              f"{t.report_cpu_s * 1000:.0f} ms CPU (medians of {t.repeats}), {t.groups} groups; the max-abs "
              f"comparison it replaces (public set) {t.old_report_s * 1000:.1f} ms")
    return 0


if __name__ == "__main__":
    run_script(main)
