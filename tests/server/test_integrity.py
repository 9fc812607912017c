"""The integrity report's grouping, on submissions as the report reads them (no server; the routes
and the sandboxed probes are tested over HTTP in tests/system/api/test_integrity.py)."""
from __future__ import annotations

import itertools
import zlib
from datetime import datetime, timezone

import numpy as np

from league.server.integrity import (
    BASELINE_COPY, IDENTICAL_FILE, NOT_PROBED, PROBE_FAILED, SAME_BEHAVIOUR, Candidate, close_pairs,
    integrity_report,
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


def report(*submissions, bundled=None, tolerance=1e-3):
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
    near_miss = candidate("dee", "d", actions(1, noise=0.05))
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


def plain_close_pairs(matrix: np.ndarray, tolerance: float) -> list[tuple[int, int]]:
    return [(i, j) for i in range(len(matrix)) for j in range(i + 1, len(matrix))
            if np.abs(matrix[i] - matrix[j]).max() <= tolerance]


def test_close_pairs_are_those_of_the_plain_definition():
    rng = np.random.default_rng(3)
    matrix = rng.uniform(-1, 1, (150, 8)).astype(np.float32)
    matrix[100:] = matrix[:50] + rng.uniform(-0.01, 0.01, (50, 8)).astype(np.float32)  # 50 near twins
    expected = plain_close_pairs(matrix, 0.02)
    assert sorted(close_pairs(matrix, 0.02)) == expected and len(expected) >= 50


def test_close_pairs_are_found_when_every_mean_is_alike():
    """Rows that are permutations of one another: the means screen nothing out."""
    rng = np.random.default_rng(4)
    values = rng.uniform(-1, 1, 8).astype(np.float32)
    matrix = np.stack([rng.permutation(values) for _ in range(60)] + [values, values + 1e-4])
    expected = plain_close_pairs(matrix, 1e-3)
    assert sorted(close_pairs(matrix, 1e-3)) == expected and (60, 61) in expected
