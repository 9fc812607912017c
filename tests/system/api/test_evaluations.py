"""Evaluation settings and re-runs on a running league: the worker evaluates again with new
settings as `league evaluate` does; a re-run of everything includes the baselines. The refusals, and
a settings change on the boards and in the grades: tests/server/api/routes/."""
from __future__ import annotations

import uuid

import pytest

from league.agents import load_agent
from league.evaluation import metrics_run

from ...server.api_calls import create_student, episodes, submission, upload, wait_for, wait_settled
from ..servers import wait_for_the_baselines


def test_a_settings_change_re_evaluates_the_submissions_with_the_new_settings(league_server, models):
    """The worker evaluates again with the new settings, as `league evaluate` does on them; going back
    to the old settings, whose results exist, re-evaluates nothing."""
    student = create_student(league_server, f"ivy-{uuid.uuid4().hex[:6]}")
    submission_id = upload(student, models["onnx"]).json()["id"]
    first = wait_settled(student, submission_id)["evaluation"]
    with league_server.client(league_server.instructor_token) as instructor:
        before = instructor.get("/api/settings/evaluation").json()
        new = {"seed": 5, "episodes": 2, "env_options": {"obstacles": False, "chicanes": False}}
        try:
            changed = instructor.put("/api/settings/evaluation", json=new).json()
            assert {key: changed[key] for key in new} == new and submission_id in changed["reevaluating"]
            assert student.get("/api/settings/evaluation").json() == new
            evaluation = wait_for(lambda: submission(student, submission_id)["evaluation"],
                                  lambda e: e["id"] != first["id"] and e["status"] == "done")
            rerun = instructor.post("/api/evaluations/rerun", json={"submission_id": submission_id})
            assert rerun.status_code == 202 and rerun.json() == {"queued": [submission_id]}
        finally:
            back = instructor.put("/api/settings/evaluation", json=before).json()
        assert submission_id not in back["reevaluating"]  # its result of these settings counts again

    assert evaluation["settings"] == new and evaluation["stale"] is False
    local = metrics_run(load_agent(models["onnx"]), episodes=2, seed=5, obstacles=False, chicanes=False).to_dict()
    served = episodes(student, submission_id, evaluation["id"])
    assert [(e["seed"], e["steps"], e["outcome"]) for e in served] == \
        [(e["seed"], e["steps"], e["outcome"]) for e in local["episodes"]]
    assert evaluation["mean_return"] == pytest.approx(local["mean_return"], abs=1e-9)
    assert evaluation["result_key"] == local["settings"]["result_key"] != first["result_key"]
    assert submission(student, submission_id)["evaluation"]["id"] == first["id"]  # the current settings' result


def test_rerun_all_queues_every_ready_submission_including_the_baselines(league_server):
    # Jobs of an earlier test (a settings change re-evaluates the baselines too) must be done first:
    # a submission being evaluated is not queued again.
    wait_for_the_baselines(league_server)
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
