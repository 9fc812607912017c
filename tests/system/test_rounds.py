"""Championship rounds on real workers: a worker killed mid-round (two workers sharing a round's heats and a failed
round raced again: test_round_heats.py).

Every heat of a round is a race job of its own; whatever happens to the workers, each heat is
raced to the end exactly once and counted once in the standings.

The killed worker's round runs on SQLite (two workers sharing a round's heats run on PostgreSQL in
test_round_heats.py): the heat's lapsed lease, reaped and re-queued with "stopped heart-beating",
is the job queue's code, tested on both backends in tests/server/jobs/test_runner.py
(test_results_of_an_attempt_that_lost_its_lease_are_discarded, test_a_job_is_claimed_by_one_attempt_only).
"""
from __future__ import annotations

import time

import pytest

from league.agents import load_agent
from league.evaluation import race

from ..server.api_calls import wait_for
from ..server.backends import TEST_SETTINGS
from .rounds import (
    LONG_HEATS, ONE_AT_A_TIME, ROUND_SETTINGS, baseline_ids, check_round_counted_once, enter_students, race_jobs,
    races_of, read_round, start_round, wait_idle, wait_round_over, worker_pid,
)
from .servers import make_server

LEASE_S = float(TEST_SETTINGS["LEAGUE_LEASE_TIMEOUT_S"])


@pytest.mark.long
@pytest.mark.parametrize("backend", ["sqlite"], indirect=True)  # the leases on PostgreSQL: test_runner.py (above)
def test_worker_killed_mid_round_every_heat_counted_once(backend, tmp_path, drivers):
    _, database_url = backend
    server = make_server(tmp_path, database_url, **ROUND_SETTINGS)
    server.start_api(embedded_worker=False)
    doomed = server.start_worker(**ONE_AT_A_TIME)
    try:
        students = enter_students(server, drivers[:5])
        wait_idle(server)
        entrants = students + baseline_ids(server)
        assert len(entrants) == 6
        championship_id, started = start_round(server, heat_size=2, include_baselines=True, env_options=LONG_HEATS)
        assert (started["number"], started["heats_total"], started["heats_done"]) == (1, 3, 0)
        race_ids = started["race_ids"]
        wait_for(lambda: race_jobs(server, race_ids), lambda jobs: any(j["status"] == "running" for j in jobs),
                 timeout=60, interval=0.05)
        # at once: a round's track is drawn secretly, and on some tracks both cars crash within 0.1 s
        doomed.kill()  # SIGKILL: the heat's lease is left behind
        doomed.wait()
        killed = [j for j in race_jobs(server, race_ids) if j["status"] == "running"]
        assert len(killed) == 1, killed  # one thread: one heat at a time
        killed_job = killed[0]
        time.sleep(LEASE_S + 1)
        in_between = read_round(server, championship_id)
        assert in_between["status"] == "running" and in_between["heats_done"] < 3, in_between
        assert races_of(server, [killed_job["race_id"]])[killed_job["race_id"]]["status"] == "running"

        server.start_worker(LEAGUE_DATA_DIR=str(tmp_path / "another-machine"), **ONE_AT_A_TIME)
        finished = wait_round_over(server, championship_id)
        races, jobs = check_round_counted_once(server, championship_id, finished, entrants)
    finally:
        server.stop_all()
    by_race = {j["race_id"]: j for j in jobs}
    again = by_race[killed_job["race_id"]]
    assert again["attempts"] == 2, again
    assert "stopped heart-beating" in again["error"] and f"/{doomed.pid}/" in again["error"], again["error"]
    assert worker_pid(again) == server.workers[1].pid  # raced again, from the start, by the other worker
    assert all(j["attempts"] == 1 and j["error"] is None for j in jobs if j is not again), jobs
    # the re-raced heat is the race its cars drive uninterrupted: same track, same order, same times
    files = {**dict(zip(students, drivers)), **{i: server.data_dir / "baselines" / "heuristic.onnx"
                                                for i in entrants if i not in students}}
    heat = races[killed_job["race_id"]]
    local = race([load_agent(files[e["submission_id"]]) for e in heat["entrants"]], seed=finished["track_seed"],
                 names=[f"{e['name']} ({e['owner']})" for e in heat["entrants"]], **LONG_HEATS)
    assert [(r["position"], r["car"], r["outcome"]) for r in heat["classification"]] == \
        [(r["position"], r["car"], r["outcome"]) for r in local.classification]
    assert [r["time"] for r in heat["classification"]] == pytest.approx([r["time"] for r in local.classification])
