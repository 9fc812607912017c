"""The integrity report's grouping, on submissions as the report reads them (no server; the routes
and the sandboxed probes are tested over HTTP in tests/system/api/test_integrity.py)."""
from __future__ import annotations

import itertools
import zlib
from datetime import datetime, timezone

import numpy as np

import pytest

from league.server.course import integrity
from league.server.course.integrity import (
    BASELINE_COPY, IDENTICAL_FILE, NOT_PROBED, PROBE_FAILED, SAME_BEHAVIOUR, Candidate, behaviour_distances,
    close_pairs, integrity_report,
)
from league.validation.probes import PROBES, probe_actions_bytes, probe_key

KEY = probe_key(5)
ids = itertools.count(1)
RNG = np.random.default_rng(7)


def actions(seed: int, noise: float = 0.0) -> bytes:
    base = np.random.default_rng(seed).uniform(-1, 1, (PROBES, 2))
    return probe_actions_bytes(base + RNG.uniform(-noise, noise, base.shape))


def candidate(owner: str, sha: str, acts: bytes | None, *, baseline: bool = False, key: str | None = KEY,
              name: str = "agent") -> Candidate:
    return Candidate(next(ids), name, zlib.crc32(owner.encode()), owner, baseline, "onnx", sha * 64, 5, key, acts,
                     datetime(2026, 11, 25, tzinfo=timezone.utc))


def report(*submissions, bundled=None, tolerance=0.1):
    return integrity_report(list(submissions), bundled=bundled or {}, tolerance=tolerance)


def test_an_identical_file_of_two_students_is_one_group_but_a_students_own_resubmission_is_none():
    a, b = candidate("ann", "a", actions(1)), candidate("bob", "a", actions(1))
    again = candidate("cy", "c", actions(3)), candidate("cy", "c", actions(3))
    groups = report(a, b, *again).groups
    assert [(g.kind, g.students, [m.id for m in g.members], g.distance) for g in groups] == \
        [(IDENTICAL_FILE, ["ann", "bob"], [a.id, b.id], 0.0)]


def test_the_same_actions_within_the_tolerance_are_the_same_behaviour_and_beyond_it_are_not():
    onnx, torchscript = candidate("ann", "a", actions(1)), candidate("bob", "b", actions(1, noise=4e-4))
    other = candidate("cy", "c", actions(2))
    near_miss = candidate("dee", "d", actions(1, noise=0.6))
    [group] = report(onnx, torchscript, other, near_miss).groups
    assert (group.kind, group.students) == (SAME_BEHAVIOUR, ["ann", "bob"])
    assert 0 < group.distance <= 1e-3


def test_a_baseline_file_is_a_copy_whether_or_not_the_baselines_account_holds_it():
    registered = candidate("baselines", "p", actions(5), baseline=True, name="ppo")
    copy = candidate("ann", "p", actions(5))
    bundled_only = candidate("bob", "t", None, key=None)
    groups = report(registered, copy, bundled_only, bundled={"t" * 64: "td3.onnx"}).groups
    assert [(g.kind, g.baseline, g.students) for g in groups] == \
        [(BASELINE_COPY, "ppo", ["ann"]), (BASELINE_COPY, "td3.onnx", ["bob"])]


def test_a_baselines_behaviour_is_a_copy_and_two_baselines_alike_are_not_reported():
    baseline = candidate("baselines", "h", actions(9), baseline=True, name="heuristic")
    twin = candidate("baselines", "i", actions(9), baseline=True, name="heuristic-again")
    rewritten = candidate("ann", "x", actions(9, noise=1e-5))
    assert report(baseline, twin).groups == []
    [group] = report(baseline, twin, rewritten).groups
    assert (group.kind, group.students, len(group.members)) == (BASELINE_COPY, ["ann"], 3)


def test_submissions_without_actions_are_listed_and_compared_by_file_only():
    unprobed = candidate("ann", "a", None, key=None)
    failed = candidate("bob", "a", None)
    old_set = candidate("cy", "c", actions(1), key="0" * 16)
    probed = candidate("dee", "d", actions(1))
    result = report(unprobed, failed, old_set, probed)
    assert [(g.kind, g.students, g.distance) for g in result.groups] == [(IDENTICAL_FILE, ["ann", "bob"], None)]
    assert [(s.id, why) for s, why in result.unprobed] == \
        [(unprobed.id, NOT_PROBED), (failed.id, PROBE_FAILED), (old_set.id, NOT_PROBED)]
    assert result.compared == 1


def plain_distance(a: np.ndarray, b: np.ndarray) -> float:
    """The behaviour distance of two agents' actions (probes, 2), one pair and one dimension at a
    time with numpy's own fits: the definition the vectorised one must meet."""
    a, b = np.clip(a.astype(np.float64), -1, 1), np.clip(b.astype(np.float64), -1, 1)
    worst, flat_everywhere = 0.0, True
    for x, y in zip(a.T, b.T, strict=True):
        flat_x, flat_y = x.std() <= 1e-3, y.std() <= 1e-3
        flat_everywhere &= flat_x and flat_y
        plain = 0.0 if flat_x and flat_y else fit_residual(x, y)
        inner = (x > x.min() + 1e-4) & (x < x.max() - 1e-4) & (y > y.min() + 1e-4) & (y < y.max() - 1e-4)
        clipped = fit_residual(x[inner], y[inner]) if inner.sum() >= 16 else 1.0
        worst = max(worst, min(plain, clipped))
    return float(np.abs(a.mean(0) - b.mean(0)).max()) if flat_everywhere else worst


def fit_residual(x: np.ndarray, y: np.ndarray) -> float:
    """The least-squares affine map's residual from x to y over y's spread (1: unrelated, mirrored or constant)."""
    if x.std() <= 1e-3 or y.std() <= 1e-3:
        return 1.0
    slope, offset = np.polyfit(x, y, 1)
    if slope <= 0:
        return 1.0
    return float(np.sqrt(((y - (slope * x + offset)) ** 2).mean()) / y.std())


def test_the_vectorised_distances_are_those_of_the_plain_definition():
    rng = np.random.default_rng(3)
    agents = rng.uniform(-1.3, 1.3, (40, PROBES, 2))
    agents[10:20] = 0.9 * agents[:10] + 0.05 + rng.normal(0, 0.02, (10, PROBES, 2))  # near copies
    agents[20:25] = np.clip(agents[:5], -0.6, 0.6)  # clipped copies
    agents[25, :, 0] = agents[26, :, 0] = 0.7  # constant throttle, both: the steering decides
    agents[27:29] = np.array([[0.2, -0.1], [0.25, -0.1]])[:, None, :]  # constant answers
    agents[29] = -agents[0]  # mirrored
    found = behaviour_distances(agents, agents)
    expected = np.array([[plain_distance(a, b) for b in agents] for a in agents])
    np.testing.assert_allclose(found, expected, atol=1e-6)
    assert found[10, 0] < 0.05 and found[20, 0] < 1e-6 and found[27, 28] == pytest.approx(0.05)
    assert found[29, 0] == 1 and np.triu(found[30:, 30:], 1)[np.triu_indices(10, 1)].min() > 0.5


def test_a_rescaled_offset_or_clipped_copy_is_near_and_an_unrelated_agent_is_far():
    rng = np.random.default_rng(5)
    agent = np.tanh(rng.normal(0, 1.5, (PROBES, 2)))
    copies = [agent * 0.98, agent * 1.5 + 0.1, np.clip(agent, -0.8, 0.8), agent + rng.normal(0, 1e-6, agent.shape),
              np.tanh(np.arctanh(np.clip(agent, -0.999, 0.999)) * 1.03)]
    other = np.tanh(rng.normal(0, 1.5, (PROBES, 2)))
    distances = behaviour_distances(agent[None], np.stack([*copies, other]))[0]
    assert distances[:-1].max() < 0.05 and distances[-1] > 0.5, distances


def test_close_pairs_are_the_pairs_within_the_tolerance_in_every_block(monkeypatch):
    monkeypatch.setattr(integrity, "ROWS_AT_ONCE", 7)  # several blocks, the last one short
    rng = np.random.default_rng(4)
    agents = rng.uniform(-1, 1, (30, PROBES, 2))
    agents[20:] = agents[:10] * 0.5 + rng.normal(0, 0.01, (10, PROBES, 2))
    matrix = behaviour_distances(agents, agents)
    expected = [(i, j) for i in range(30) for j in range(i + 1, 30) if matrix[i, j] <= 0.1]
    assert sorted(close_pairs(agents, 0.1)) == expected and len(expected) >= 10
