"""The deadline-rush benchmark (benchmarks/bench_rush.py) at a smoke size: a course of 12 students
uploads 30 agents (3 broken) in a few seconds to two workers while clients poll, then races a
round; its checks (no job lost, stuck or done twice, results equal to local metrics_run, broken
uploads refused with a reason, the round complete) must pass. Its timings are printed, not checked."""
from __future__ import annotations

import sys

import pytest

from ..server.conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import bench_rush


@pytest.mark.long
def test_a_small_rush_passes_the_benchmarks_checks(capsys):
    """On SQLite: the PostgreSQL + Redis path of the same jobs runs in test_hosts.py and the benchmark."""
    code = bench_rush.main(["--backend", "sqlite", "--students", "12", "--uploads", "30", "--window-s", "5",
                            "--episodes", "3", "--distinct", "8", "--idle-s", "1"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "checks: all passed" in out
    assert "30 uploads in" in out and "27 ready, 3 rejected" in out
