"""Each benchmark's measuring function at its smallest size: it runs, and its figures are there,
finite and positive, with the counts asked for. Timings are never checked against targets here
(a busy machine would fail them); the benchmarks print those.

Not run here: bench_reference.py (it needs a checkout of the original MicroRacer) and
baselines_report.py (finished training runs); of bench_server.py only (a), of bench_league.py only
(a): their other parts start several leagues and race rounds for minutes at any size. The rush
at a small size is tests/system/test_rush.py (with its checks). bench_claims.py runs on SQLite
here (PostgreSQL in the benchmark).

bench_queue.py, bench_course.py (its course and its backlog run) and bench_backup.py start a league
of servers (`serve` and workers): 10-30 s each at their smallest size on a quiet 2-CPU machine, a
minute or more on a busy one (marked `long`: this file starts first in the whole suite). The file
takes about 90 s.
"""
from __future__ import annotations

import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_backup  # noqa: E402
import bench_baselines  # noqa: E402
import bench_claims  # noqa: E402
import bench_course  # noqa: E402
import bench_grades  # noqa: E402
import bench_integrity  # noqa: E402
import bench_league  # noqa: E402
import bench_metrics  # noqa: E402
import bench_queue  # noqa: E402
import bench_server  # noqa: E402
import bench_simulator  # noqa: E402
import bench_toolkit  # noqa: E402


def positive(*values: float) -> bool:
    return all(math.isfinite(value) and value > 0 for value in values)


def test_simulator():
    rows = bench_simulator.measure(scale=0.01)
    assert len(rows) == 23  # no --reference, no --before
    assert [row.name for row in rows][:2] == ["reset, new random track, all options on", "MicroRacerEnv.step, one car"]
    share = {row.name.strip(): row for row in rows if row.name.startswith("  8 envs:")}
    assert list(share) == ["8 envs: new tracks' share of the loop", "8 envs: the ratio to sync were new tracks free",
                           "8 envs: the ratio to sync with a reset of 0.5 ms", "8 envs: the reset 5x needs"]
    assert 0 <= share["8 envs: new tracks' share of the loop"].value < 100  # (0 when the pool's loop is slower)
    assert positive(*(row.value for row in rows if not row.name.startswith("  8 envs:")),
                    share["8 envs: the ratio to sync were new tracks free"].value)
    assert {row.unit for row in rows} == {"us", "car-steps/s", "steps/s", "%", "x"}


def test_toolkit(tmp_path):
    f = bench_toolkit.measure(episodes=2, out=tmp_path, cars=2)
    assert f.episodes == 2 and 0 <= f.completed <= 2 and 0 <= f.plain_completed <= 2
    assert f.steps >= 2 and f.cars == 2 and f.race_steps > 0 and 0 <= f.finishers <= 2
    assert 0 <= f.outcome_or_steps_changed <= 2 and f.outcomes_changed <= f.outcome_or_steps_changed
    assert f.largest_return_difference >= 0
    assert positive(f.plain_s, f.one_at_a_time_s, f.cold_s, f.warm_s, f.race_s, f.gif_s, f.replay_kib, f.gif_kib,
                    f.onnx_fixed_before_s, f.onnx_fixed_after_s, f.torchscript_fixed_before_s,
                    f.torchscript_fixed_after_s)
    assert f.onnx_fixed_path in ("row by row", "free batch")
    assert (tmp_path / "race.gif").stat().st_size == round(f.gif_kib * 1024)
    bench_toolkit.report(f)  # prints every figure


def test_baselines_loop():
    f = bench_baselines.measure(updates=3, warmup=100)
    assert f.iterations == 3 and f.threads >= 1
    assert list(f.parts_s) == list(bench_baselines.PARTS) and positive(*f.parts_s.values())
    assert sum(f.parts_s.values()) <= f.total_s and positive(f.ms_per_iteration)


def test_baselines_final_and_best_actors(tmp_path, capsys):
    from league.baselines import ddpg
    from league.baselines.common.run import Run

    args = ddpg.Args(steps=300, learning_starts=100, eval_every=150, eval_episodes=2, final_eval_episodes=0,
                     checkpoint_every=0)
    run = Run(tmp_path / "ddpg-1", "ddpg", args, progress=False, tensorboard=False)
    ddpg.train(args, run)
    run.close()
    rows = bench_baselines.measure_actors(tmp_path)
    assert [(r.algorithm, r.seed) for r in rows] == [("ddpg", 1)]
    assert all(0 <= e["completed"] <= e["episodes"] == 100 for e in (rows[0].final, rows[0].best))
    bench_baselines.report_actors(rows)
    assert "thesis mean 38" in capsys.readouterr().out


def test_integrity():
    distances = bench_integrity.distances()
    assert list(distances.formats) == list(bench_integrity.SPEEDS)
    assert len(distances.drivers) == 6 and len(distances.baselines) == 15
    assert list(distances.copies) == list(bench_integrity.VARIANTS)
    assert all(len(values) == 6 for values in distances.copies.values())
    # what the benchmark shows: copies, whatever their disguise, are far closer than distinct agents
    copies = [min(public, secret) for values in distances.copies.values() for public, secret, _ in values]
    distinct = [d for pair in [*distances.drivers.values(), *distances.baselines] for d in pair]
    assert max(max(distances.formats.values())) < max(copies) < 0.05 < 0.2 < min(distinct)
    t = bench_integrity.report_time(30, 1, np.random.default_rng(0))
    assert t.submissions == 30 and t.repeats == 1 and t.groups >= 0 and positive(t.report_s, t.old_report_s)


def test_grades():
    f = bench_grades.measure(bench_grades.parse(["--students", "3", "--repeat", "1"]))
    assert f.backend == "sqlite" and f.students == 3 and f.rows >= 3  # the baselines' rows beside
    assert len(f.ms) == 6 and positive(f.built_s, *f.ms.values())


def test_metrics():
    f = bench_metrics.measure(bench_metrics.parse(["--students", "2", "--uploads", "3", "--episodes", "2",
                                                   "--races", "2", "--scrapes", "2"]))
    assert (f.students, f.submissions, f.episodes, f.jobs) == (2, 3, 6, 8)
    assert list(f.ms) == [label for label, _ in bench_metrics.REQUESTS]
    assert all(len(times) == 2 and positive(*times) for times in f.ms.values())


@pytest.mark.parametrize("path", bench_claims.PATHS)
def test_claims_on_sqlite(path):
    args = bench_claims.parse(["--backend", "sqlite", "--processes", "2", "--owners", "5", "--depths", "12",
                               "--claims", "10"])
    f = bench_claims.measure_depth(args, 12, path)
    assert f.failures == [] and (f.depth, f.path, f.claimed, f.double_claims) == (12, path, 10, 0)
    assert positive(f.wall_s, f.jobs_per_s, *f.claim_ms.values()) and f.misses >= 0
    assert math.isnan(f.database_cpu_s)  # SQLite runs inside the claimers


def test_server_evaluation(tmp_path):
    """(a): the plain loop, lockstep metrics_run, and the same in a sandbox."""
    from _league import thesis_actor

    f = bench_server.bench_evaluation(thesis_actor(tmp_path), episodes=2)
    assert f.episodes == 2 and 0 <= f.completed <= 2
    assert positive(f.first_sandbox_s, f.sandbox_start_s, f.plain_s, f.lockstep_s, f.cached_lockstep_s,
                    f.sandboxed_s, f.cached_sandboxed_s)
    bench_server.report_evaluation(f)


def test_league_heat(tmp_path):
    """(a): a heat in sandboxes on one core, beside the same race in this process."""
    f = bench_league.bench_heat(bench_league.student_models(tmp_path, 2), repeats=1)
    assert f.cars == 2 and len(f.totals) == len(f.starts) == 1 and f.steps > 0
    assert f.identical  # a sandboxed race classifies as the in-process one
    assert positive(*f.totals, *f.starts, f.in_process_s) and f.starts[0] <= f.totals[0]


def test_league_heat_waits_split_a_rounds_time():
    """(b)'s breakdown of a round from its heats' (worker, claimed, finished) times."""
    spans = [("7", 0.4, 2.0), ("8", 0.5, 1.5), ("7", 2.1, 3.0), ("8", 1.8, 2.5), ("8", 2.5, 4.5)]
    waits = bench_league.heat_waits(spans)
    assert waits.first_claim_s == 0.4
    assert waits.idle_s == pytest.approx(0.1 + 0.3 + 0.0)  # 7: 2.0 -> 2.1; 8: 1.5 -> 1.8, 2.5 -> 2.5
    assert waits.tail_s == pytest.approx(4.5 - 3.0) and waits.busiest_s == pytest.approx(1.0 + 0.7 + 2.0)


@pytest.mark.long
def test_queue_on_sqlite():
    case = bench_queue.measure_case("sqlite", 0.5, False, jobs=2, rng=random.Random(0))
    assert (case.backend, case.wake, len(case.latencies)) == ("sqlite", False, 2)
    assert positive(*case.latencies)


@pytest.mark.long
def test_course():
    f = bench_course.measure(bench_course.parse(["--students", "2", "--episodes", "1", "--distinct", "2"]))
    assert f.failures == [] and (f.students, f.episodes, f.finals) == (2, 1, 2)
    assert positive(f.public_s, f.publish_s, f.private_span_s)


@pytest.mark.long
def test_course_backlog():
    """The backlog run: every upload still queued at the due time, each student still gets their final,
    its private evaluation and a grade before the board publishes itself."""
    f = bench_course.measure_backlog(bench_course.parse(["--backlog", "--students", "3", "--episodes", "1",
                                                         "--distinct", "2", "--window", "8"]))
    assert f.failures == [] and (f.students, f.uploaded, f.graded, f.without_final) == (3, 3, 3, 0)
    assert positive(f.publish_s, f.jobs_s) and f.after_last_s >= 0


@pytest.mark.long
def test_backup():
    f = bench_backup.measure(bench_backup.parse(["--students", "2", "--uploads", "3", "--rounds", "1",
                                                 "--episodes", "1", "--distinct", "2", "--repeats", "1",
                                                 "--restore-into", "same"]))
    assert f.failures == [] and list(f.restores) == ["sqlite"] and len(f.backup_s) == 1
    assert set(f.rows) == set(bench_backup.TABLES) and f.rows["users"] >= 2 and f.rows["races"] >= 1
    assert positive(f.evaluated_s, f.rounds_s, f.database_mb, f.backup_mb, *f.backup_s,
                    *f.restores["sqlite"].values())
