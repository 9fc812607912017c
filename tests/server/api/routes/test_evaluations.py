"""Evaluation settings and re-runs: over real HTTP with a worker, and the refusals in process."""
from __future__ import annotations

import uuid

import pytest

from league.agents import load_agent
from league.evaluation import metrics_run
from league.server.db.models import REJECTED

from ...conftest import create_student, episodes, submission, upload, wait_for, wait_settled


def test_instructor_changes_settings_and_reruns_one_submission(league_server, models):
    student = create_student(league_server, f"ivy-{uuid.uuid4().hex[:6]}")
    submission_id = upload(student, models["onnx"]).json()["id"]
    first = wait_settled(student, submission_id)["evaluation"]
    with league_server.client(league_server.instructor_token) as instructor:
        before = instructor.get("/api/settings/evaluation").json()
        new = {"seed": 5, "episodes": 2, "env_options": {"obstacles": False, "chicanes": False}}
        try:
            assert instructor.put("/api/settings/evaluation", json=new).json() == new
            assert student.get("/api/settings/evaluation").json() == new
            rerun = instructor.post("/api/evaluations/rerun", json={"submission_id": submission_id})
            assert rerun.status_code == 202 and rerun.json() == {"queued": [submission_id]}
        finally:
            instructor.put("/api/settings/evaluation", json=before)

    evaluation = wait_for(lambda: submission(student, submission_id)["evaluation"],
                          lambda e: e["id"] != first["id"] and e["status"] == "done")

    assert evaluation["settings"] == new
    local = metrics_run(load_agent(models["onnx"]), episodes=2, seed=5, obstacles=False, chicanes=False).to_dict()
    served = episodes(student, submission_id, evaluation["id"])
    assert [(e["seed"], e["steps"], e["outcome"]) for e in served] == \
        [(e["seed"], e["steps"], e["outcome"]) for e in local["episodes"]]
    assert evaluation["mean_return"] == pytest.approx(local["mean_return"], abs=1e-9)


def test_rerun_all_queues_every_ready_submission_including_the_baselines(league_server):
    with league_server.client(league_server.instructor_token) as instructor:
        ready = {s["id"] for s in instructor.get("/api/submissions", params={"all": True}).json()
                 if s["status"] == "ready"}
        rerun = instructor.post("/api/evaluations/rerun", json={"all": True})
        assert rerun.status_code == 202
        assert ready <= set(rerun.json()["queued"])
        baseline = next(s for s in instructor.get("/api/submissions", params={"all": True}).json()
                        if s["owner"] == "baselines")
        assert baseline["id"] in rerun.json()["queued"]
        wait_for(lambda: submission(instructor, baseline["id"])["evaluation"], lambda e: e["status"] == "done")


@pytest.mark.parametrize("options, message", [
    ({"observation": "lidar"}, "observation is not an evaluation setting: it follows each agent's input size"),
    ({"warp_drive": True}, "invalid env_options: RaceOptions() got an unexpected keyword argument 'warp_drive'; valid options: "),
    ({"track_width": 5.0}, "invalid env_options: track_width must be in (0, "),
])
def test_invalid_env_options_are_refused(app_league, options, message):
    with app_league.client(app_league.instructor_token) as instructor:
        response = instructor.put("/api/settings/evaluation", json={"seed": 1, "episodes": 3, "env_options": options})
    assert response.status_code == 422
    assert response.json()["detail"].startswith(message)


def test_rerun_of_a_rejected_submission_is_a_conflict(app_league):
    user, _ = app_league.student("jay")
    rejected = app_league.submission(user, status=REJECTED).id
    with app_league.client(app_league.instructor_token) as instructor:
        response = instructor.post("/api/evaluations/rerun", json={"submission_id": rejected})
        assert response.status_code == 409
        assert response.json() == {"detail": f"submission {rejected} is rejected: only ready submissions are evaluated"}
        assert instructor.post("/api/evaluations/rerun", json={}).status_code == 422
