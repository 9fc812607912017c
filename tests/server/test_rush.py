"""The deadline-rush benchmark (benchmarks/bench_rush.py) at a smoke size: a course of 20 students
uploads 40 agents (4 broken; on PostgreSQL 10 students, 20 agents) in a few seconds to two workers while clients poll, then races a
round; its checks (no job lost, stuck or done twice, results equal to local metrics_run, broken
uploads refused with a reason, the round complete) must pass. Its timings are printed, not checked."""
from __future__ import annotations

import sys

import pytest

from .conftest import REPO, _postgres_available

sys.path.insert(0, str(REPO / "benchmarks"))
import bench_rush  # noqa: E402


@pytest.mark.parametrize("kind, students, uploads", [("sqlite", 20, 40), ("postgres", 10, 20)])
def test_a_small_rush_passes_the_benchmarks_checks(kind, students, uploads, capsys):
    if kind == "postgres" and (reason := _postgres_available()):
        pytest.skip(reason)
    code = bench_rush.main(["--backend", kind, "--students", str(students), "--uploads", str(uploads),
                            "--window-s", "6", "--episodes", "3", "--distinct", "8", "--idle-s", "1"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "checks: all passed" in out
    broken = uploads // 10
    assert f"{uploads} uploads in" in out and f"{uploads - broken} ready, {broken} rejected" in out
