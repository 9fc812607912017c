"""The audit log: each instructor action leaves one event (who, what, on what), readable by
instructors only, as pages and as a CSV that no spreadsheet runs as formulas."""
from __future__ import annotations

import csv
import io

import pytest
from sqlalchemy import select

from league.server.db.models import DONE, Job

from ...api_calls import unique
from ...backends import BACKENDS
from ..in_process import in_process_league


@pytest.mark.parametrize("kind", BACKENDS)
def test_every_instructor_action_is_recorded_and_only_instructors_read_them(kind, tmp_path):
    with in_process_league(kind, tmp_path, bootstrap=False) as league:
        student, student_client = league.student("sam")
        agent = league.submission(student)
        with league.sessions.begin() as session:  # its validation over; its evaluation job still queued
            session.execute(Job.__table__.update().where(Job.submission_id == agent.id, Job.kind == "validate")
                            .values(status=DONE))
            queued = session.scalar(select(Job.id).where(Job.submission_id == agent.id, Job.status == "queued"))
        with league.client(league.instructor_token) as instructor:
            created = instructor.post("/api/users", json={"name": unique("ivy")}).json()
            roster = instructor.post("/api/users/roster", files={"file": ("r.csv", f"name\n{unique('rex')}\n")}).json()
            steps = [
                instructor.post(f"/api/users/{created['id']}/revoke"),
                instructor.post(f"/api/users/{created['id']}/token"),
                instructor.post(f"/api/jobs/{queued}/cancel"),
                instructor.post("/api/evaluations/rerun", json={"submission_id": agent.id}),
                instructor.put("/api/settings/evaluation", json={"seed": 7, "episodes": 2, "env_options": {}}),
                cup := instructor.post("/api/championships", json={"name": "cup", "include_baselines": False}),
                run := instructor.post(f"/api/championships/{cup.json()['id']}/rounds"),
            ]
            with league.sessions() as session:  # its heat cancelled: the round failed, to be retried
                heat_job = session.scalar(select(Job.id).where(Job.race_id == run.json()["race_ids"][0]))
            steps += [instructor.post(f"/api/jobs/{heat_job}/cancel"),
                      instructor.post(f"/api/championships/{cup.json()['id']}/rounds/1/retry"),
                      instructor.delete(f"/api/users/{created['id']}")]
            page = instructor.get("/api/audit", params={"size": 100}).json()
            first_two = instructor.get("/api/audit", params={"size": 2, "page": 1}).json()
            spreadsheet = instructor.get("/api/audit.csv")
        with student_client as sam:
            refused = [sam.get("/api/audit"), sam.get("/api/audit.csv")]
        with league.client() as anonymous:
            anonymous_answer = anonymous.get("/api/audit")

    assert all(step.status_code < 300 for step in steps), [step.text for step in steps]
    events = list(reversed(page["items"]))
    assert [e["action"] for e in events] == [
        "user.create", "user.import", "user.revoke", "user.token", "job.cancel", "evaluation.rerun",
        "settings.evaluation", "championship.create", "round.run", "job.cancel", "round.retry", "user.delete"]
    assert {e["actor_name"] for e in events} == {"prof"} and page["total"] == 12
    by_action = {}
    for event in events:
        by_action.setdefault(event["action"], event)  # the first of each (job.cancel: the evaluation's)
    assert by_action["user.revoke"]["target_id"] == by_action["user.delete"]["target_id"] == created["id"]
    assert by_action["user.import"]["details"]["created"] == [roster["created"][0]["id"]]
    assert by_action["job.cancel"]["target_id"] == queued
    assert by_action["job.cancel"]["details"] == {"kind": "evaluate", "submission_id": agent.id, "race_id": None}
    assert events[9]["target_id"] == heat_job and events[9]["details"]["kind"] == "race"
    assert by_action["settings.evaluation"]["details"]["settings"] == {"seed": 7, "episodes": 2, "env_options": {}}
    assert by_action["round.run"]["details"]["round"] == by_action["round.retry"]["details"]["round"] == 1
    assert by_action["round.retry"]["details"]["heats"] == 1
    assert created["name"] not in str(by_action["user.delete"])  # a deleted student's name is not kept
    assert all(created["token"] not in str(e) for e in events)
    assert [e["action"] for e in first_two["items"]] == ["user.delete", "round.retry"]
    rows = list(csv.reader(io.StringIO(spreadsheet.text)))
    assert spreadsheet.headers["content-type"].startswith("text/csv")
    assert rows[0] == ["at", "actor_id", "actor_name", "action", "target_kind", "target_id", "details"]
    assert [row[3] for row in rows[1:]] == [e["action"] for e in reversed(events)]
    assert [r.status_code for r in refused] == [403, 403] and anonymous_answer.status_code == 401
