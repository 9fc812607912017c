"""The deadline-rush benchmark (benchmarks/bench_rush.py) at a smoke size: a course of 12 students
uploads 30 agents (3 broken) in a few seconds to two workers while clients poll, then races a
round; its checks (no job lost, stuck or done twice, results equal to local metrics_run, broken
uploads refused with a reason, the round complete) must pass. Its timings are measured, not checked."""
from __future__ import annotations

import math
import sys

import pytest

from ..server.commands import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import bench_rush


@pytest.mark.long
def test_a_small_rush_passes_the_benchmarks_checks():
    """On SQLite: the PostgreSQL + Redis path of the same jobs runs in test_hosts.py and the benchmark."""
    figures = bench_rush.measure(bench_rush.parse([
        "--backend", "sqlite", "--students", "12", "--uploads", "30", "--window-s", "5", "--episodes", "3",
        "--distinct", "8", "--idle-s", "1"]))
    assert figures.failures == []
    assert (figures.uploads, figures.accepted, figures.broken, figures.refused_at_upload) == (30, 30, 3, 0)
    assert (figures.ready, figures.rejected) == (27, 3)  # the broken ones refused by validation
    assert figures.heats == 2 and figures.cars == 12  # every student's active agent, heats of <= 10
    for phases in figures.latencies.values():
        assert phases["rush"]["answers"] > 0 and 0 < phases["rush"]["p50"] <= phases["rush"]["p99"]
    assert all(math.isfinite(value) and value > 0 for value in (figures.upload_s, figures.round_s))
    assert figures.drain_s >= 0
    waits = figures.round_waits  # where the round's time went: the heats, the queue's waits
    assert 0 < waits.busiest_s <= figures.heats_s and waits.first_claim_s >= 0 and waits.idle_s >= 0
    assert 0 <= waits.tail_s < figures.round_s
