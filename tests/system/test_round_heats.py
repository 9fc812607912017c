"""Championship rounds on real workers, continued: two workers sharing a round's heats, and a failed
round whose failed heats are raced again (a file of their own, so that the two pytest workers share
the rounds' tests: each is a league of real processes for a minute or more).
"""
from __future__ import annotations

import time
from collections import Counter

import pytest

from league.server.jobs.placement import CpuSlots

from ..server.api_calls import create_student, wait_for
from ..server.backends import TEST_SETTINGS, fresh_backend
from .rounds import (
    LONG_HEATS, ONE_AT_A_TIME, ROUND_SETTINGS, check_round_counted_once, enter_students, race_jobs, races_of,
    standings, start_round, wait_idle, wait_round_over, worker_pid,
)
from .servers import make_server

LEASE_S = float(TEST_SETTINGS["LEAGUE_LEASE_TIMEOUT_S"])


@pytest.mark.long
def test_two_workers_share_the_heats_of_a_round(tmp_path, drivers):
    with fresh_backend("postgres", tmp_path) as database_url:
        server = make_server(tmp_path, database_url, LEAGUE_BOOTSTRAP="false", **ROUND_SETTINGS)
        try:
            server.start_api(embedded_worker=False)
            for k in range(2):  # two machines, each with its own disk: the models come from the database
                server.start_worker(LEAGUE_DATA_DIR=str(tmp_path / f"machine-{k}"), **ONE_AT_A_TIME)
            entrants = enter_students(server, drivers)
            wait_idle(server)
            championship_id, started = start_round(server, heat_size=2, include_baselines=False)
            assert started["heats_total"] == 4
            finished = wait_round_over(server, championship_id)
            _, jobs = check_round_counted_once(server, championship_id, finished, entrants)
            slots = CpuSlots(tmp_path / "cpu-slots").held()  # the CPUs of this machine are split between them
        finally:
            server.stop_all()
    assert slots == [0, 1]
    assert all(j["attempts"] == 1 and j["error"] is None for j in jobs), jobs
    pids = {worker.pid for worker in server.workers}  # both took part: heats were shared, none raced twice
    by_worker = Counter(worker_pid(j) for j in jobs)
    assert set(by_worker) == pids, f"heats per worker pid {dict(by_worker)}; workers {pids}"


@pytest.mark.long
def test_a_failed_round_races_its_failed_heats_again(tmp_path, drivers):
    """A heat whose job fails for good (here: its worker is killed and no attempt is left) fails
    the round, which counts for nothing until an instructor races its failed heats again."""
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url, LEAGUE_MAX_JOB_ATTEMPTS="1", LEAGUE_BOOTSTRAP="false",
                             **ROUND_SETTINGS)
        server.start_api(embedded_worker=False)
        doomed = server.start_worker(**ONE_AT_A_TIME)
        instructor, student = server.client(server.instructor_token), create_student(server, "sam")
        try:
            entrants = enter_students(server, drivers[:4])
            wait_idle(server)
            championship_id, started = start_round(server, heat_size=2, include_baselines=False,
                                                   env_options=LONG_HEATS)
            rounds = f"/api/championships/{championship_id}/rounds"
            running = wait_for(lambda: race_jobs(server, started["race_ids"]),
                               lambda jobs: any(j["status"] == "running" for j in jobs), timeout=60, interval=0.05)
            failing = next(j["race_id"] for j in running if j["status"] == "running")
            doomed.kill()
            doomed.wait()
            time.sleep(LEASE_S + 1)
            server.start_worker(**ONE_AT_A_TIME)  # its reaper gives the heat up: no attempt left
            failed = wait_round_over(server, championship_id)
            failed_race = races_of(server, [failing])[failing]
            nothing_counted = standings(server, championship_id)
            refusals = {"student": student.post(f"{rounds}/1/retry"), "unknown": instructor.post(f"{rounds}/2/retry")}

            retried = instructor.post(f"{rounds}/1/retry")
            finished = wait_round_over(server, championship_id)
            _, jobs = check_round_counted_once(server, championship_id, finished, entrants, retried=(failing,))
            refusals["done"] = instructor.post(f"{rounds}/1/retry")
        finally:
            instructor.close()
            student.close()
            server.stop_all()
    assert failed["status"] == "failed" and failed["heats_done"] == 1, failed
    assert failed_race["status"] == "failed"
    assert failed_race["error"].startswith("the race could not be completed: ") and \
        "stopped heart-beating" in failed_race["error"], failed_race["error"]
    assert nothing_counted == {"items": [], "total": 0}
    assert retried.status_code == 202, retried.text
    assert (retried.json()["status"], retried.json()["heats_done"]) == ("running", 1)  # a heat done, one to race
    assert [j["attempts"] for j in jobs] == [1, 1] and all(j["error"] is None for j in jobs)
    assert {name: (r.status_code, r.json()["detail"]) for name, r in refusals.items()} == {
        "student": (403, "only instructors may do this"),
        "unknown": (404, f"championship {championship_id} has no round 2"),
        "done": (409, "round 1 is done: only a failed round is raced again")}
