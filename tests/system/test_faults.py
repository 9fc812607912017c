"""Faults: a worker killed with SIGKILL mid-evaluation (on PostgreSQL, the backend of workers on other
machines), and a league restarted (on SQLite, `league serve`'s own backend: its file is what a kill
mid-write could damage).

Each runs on one backend: what is backend-specific in them, the job leases in the jobs table, runs
on both backends in tests/server/jobs/test_runner.py, in process: a lapsed lease reaped, re-queued
with "stopped heart-beating" and its late results discarded
(test_results_of_an_attempt_that_lost_its_lease_are_discarded), a fresh one left alone
(test_reaper_leaves_fresh_leases_alone), one claim of a job at a time
(test_a_job_is_claimed_by_one_attempt_only), and a worker's jobs handed back when it stops with
SIGTERM (test_a_worker_shutting_down_hands_its_jobs_back).
"""
from __future__ import annotations

import signal
import time

import pytest

from league.agents import load_agent
from league.evaluation import metrics_run

from ..server.api_calls import create_student, episodes, submission, upload, wait_for, wait_settled
from ..server.backends import TEST_SETTINGS
from .servers import make_server

LONG_EPISODES = "100"  # an evaluation of a second or more (lockstep): long enough to be stopped in the middle
LEASE_S = float(TEST_SETTINGS["LEAGUE_LEASE_TIMEOUT_S"])


def evaluation_status(client, submission_id: int) -> str | None:
    return (submission(client, submission_id)["evaluation"] or {}).get("status")


def jobs_of(server, submission_id: int) -> list[dict]:
    with server.client(server.instructor_token) as instructor:
        return [j for j in instructor.get("/api/jobs").json() if j["submission_id"] == submission_id]


@pytest.mark.parametrize("backend", ["postgres"], indirect=True)  # the leases on SQLite: test_runner.py (above)
def test_worker_killed_mid_evaluation_the_evaluation_completes_once(backend, tmp_path, models):
    _, database_url = backend
    server = make_server(tmp_path, database_url, LEAGUE_EVAL_EPISODES=LONG_EPISODES)
    server.start_api(embedded_worker=False)
    doomed = server.start_worker()
    try:
        student = create_student(server, "kim")
        submission_id = upload(student, models["onnx"]).json()["id"]
        wait_for(lambda: evaluation_status(student, submission_id), lambda s: s == "running", timeout=60)
        doomed.send_signal(signal.SIGSTOP)  # frozen where it is: it can neither finish nor heart-beat
        assert evaluation_status(student, submission_id) == "running"
        doomed.kill()  # SIGKILL: no goodbye, the lease is left behind
        doomed.wait()
        time.sleep(LEASE_S + 1)
        assert evaluation_status(student, submission_id) == "running"  # nobody else works on it yet

        elsewhere = tmp_path / "another-machine"
        server.start_worker(LEAGUE_DATA_DIR=str(elsewhere))  # no shared disk: models come from the database
        result = wait_settled(student, submission_id, timeout=120)
        served = episodes(student, submission_id, result["evaluation"]["id"], limit=7)
        jobs = jobs_of(server, submission_id)
    finally:
        server.stop_all()
    evaluation = result["evaluation"]
    assert result["status"] == "ready" and evaluation["status"] == "done", evaluation["error"]
    assert [e["index"] for e in served] == list(range(int(LONG_EPISODES)))
    evaluate_job = next(j for j in jobs if j["kind"] == "evaluate")
    assert (evaluate_job["status"], evaluate_job["attempts"]) == ("done", 2)
    assert "stopped heart-beating" in evaluate_job["error"]
    assert (elsewhere / "blobs" / result["sha256"][:2] / result["sha256"]).read_bytes() == models["onnx"].read_bytes()
    local = metrics_run(load_agent(models["onnx"]), episodes=int(LONG_EPISODES), seed=11).to_dict()
    assert [(e["seed"], e["steps"], e["outcome"]) for e in served] == \
        [(e["seed"], e["steps"], e["outcome"]) for e in local["episodes"]]
    assert evaluation["mean_return"] == pytest.approx(local["mean_return"], abs=1e-9)


@pytest.mark.long
@pytest.mark.parametrize("backend", ["sqlite"], indirect=True)  # the leases on PostgreSQL: test_runner.py (above)
def test_restart_loses_nothing_and_leaves_nothing_stuck(backend, tmp_path, models):
    _, database_url = backend
    server = make_server(tmp_path, database_url, LEAGUE_EVAL_EPISODES=LONG_EPISODES)
    server.start_api()
    try:
        student = create_student(server, "lee")
        done = [upload(student, models[key]).json()["id"] for key in ("heuristic_onnx", "random_bytes")]
        before = {i: wait_settled(student, i, timeout=120) for i in done}
        interrupted = upload(student, models["onnx"]).json()["id"]
        wait_for(lambda: evaluation_status(student, interrupted), lambda s: s == "running", timeout=60)
        server.stop(server.api, kill=True)  # API and its embedded worker die mid-evaluation

        server.start_api()
        after = {i: submission(student, i) for i in done}
        finished = wait_settled(student, interrupted, timeout=120)
        finished_episodes = episodes(student, interrupted, finished["evaluation"]["id"])
        with server.client(server.instructor_token) as instructor:  # every job ends (the baseline's too,
            # whose evaluation may have been queued or running at the kill, and is raced again after it)
            unfinished = wait_for(lambda: [j for j in instructor.get("/api/jobs").json()
                                           if j["status"] in ("queued", "running")],
                                  lambda jobs: jobs == [], timeout=120, interval=0.25)
        server.stop(server.api)  # a clean stop (SIGTERM) and a second restart
        server.start_api()
        again = {i: submission(student, i) for i in [*done, interrupted]}
    finally:
        server.stop_all()
    assert stored(after) == stored(before)
    assert finished["status"] == "ready" and finished["evaluation"]["status"] == "done"
    assert len(finished_episodes) == int(LONG_EPISODES)
    assert unfinished == []
    assert stored(again) == stored({**before, interrupted: finished})
    # "active" is derived, not stored: the latest ready submission, once the interrupted one is ready
    assert [i for i, s in again.items() if s["active"]] == [interrupted]


def stored(submissions: dict[int, dict]) -> dict[int, dict]:
    return {i: {key: value for key, value in s.items() if key != "active"} for i, s in submissions.items()}
