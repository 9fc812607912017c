"""The audit log: each instructor action leaves one event (who, what, on what), readable by
instructors only, as pages and as a CSV that no spreadsheet runs as formulas."""
from __future__ import annotations

import csv
import io
from datetime import datetime, timedelta, timezone

import pytest
from sqlalchemy import select

from league.server.db.models import DONE, AuditEvent, Job

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
    cancelled = by_action["job.cancel"]["details"]
    assert (cancelled["kind"], cancelled["submission_id"], cancelled["race_id"]) == ("evaluate", agent.id, None)
    assert (cancelled["before"], cancelled["after"]) == ({"status": "queued"}, {"status": "failed"})
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


T1 = datetime(2030, 3, 8, 23, 59, tzinfo=timezone.utc)
T2 = datetime(2030, 3, 10, 23, 59, tzinfo=timezone.utc)
RUBRIC = {"kind": "points", "max_points": 10, "completed": {"kind": "linear", "points": 6},
          "rank": {"kind": "table", "points": [4, 2, 1]}}


def iso(moment: datetime) -> str:
    return moment.isoformat(timespec="seconds")


@pytest.mark.parametrize("kind", BACKENDS)
def test_every_change_of_a_grade_or_a_deadline_is_recorded_with_the_values_before_and_after(kind, tmp_path,
                                                                                           monkeypatch):
    """Creating and editing an assignment (due time, late policy), extensions, a rubric, publishing (by
    the instructor, and by the assignment itself), a re-run, a cancelled job, the evaluation
    settings, a backup and a restore: one event each, with what was before and what is after."""
    from league.server.app import catch_up
    from league.server.cli import main

    with in_process_league(kind, tmp_path, bootstrap=False) as league:
        clock = league.app.state.services.clock
        clock.set(T1 - timedelta(days=1))
        student, _ = league.student("sue")
        agent = league.submission(student)
        with league.sessions.begin() as session:
            session.execute(Job.__table__.update().values(status=DONE))
        with league.client(league.instructor_token) as instructor:
            hw = instructor.post("/api/assignments", json={"name": "hw", "episodes": 4, "due_at": iso(T1),
                                                           "late_until": iso(T2), "late_penalty": 0.5}).json()
            url = f"/api/assignments/{hw['id']}"
            steps = [instructor.patch(url, json={"due_at": iso(T1 + timedelta(hours=1)), "late_penalty": 0.8}),
                     instructor.patch(url, json={"late_penalty": 0.8}),  # no change: no event
                     instructor.put(f"{url}/extensions/{student.id}", json={"due_at": iso(T2)}),
                     instructor.delete(f"{url}/extensions/{student.id}"),
                     instructor.put(f"{url}/rubric", json=RUBRIC),
                     instructor.post("/api/evaluations/rerun", json={"submission_id": agent.id})]
            with league.sessions() as session:
                rerun_job = session.scalar(select(Job.id).where(Job.submission_id == agent.id, Job.status == "queued"))
            steps += [instructor.post(f"/api/jobs/{rerun_job}/cancel"),
                      instructor.put("/api/settings/evaluation", json={"seed": 7, "episodes": 2, "env_options": {}})]
            auto = instructor.post("/api/assignments", json={"name": "auto", "episodes": 4, "due_at": iso(T1),
                                                             "auto_publish": True}).json()
            clock.set(T2 + timedelta(seconds=1))
            catch_up(league.app.state.services)  # every final frozen: "auto" publishes itself
            steps.append(instructor.post(f"{url}/publish"))
        monkeypatch.setenv("LEAGUE_DATABASE_URL", league.settings.database_url)
        assert main(["backup", str(tmp_path / "league.backup"), "--data-dir", str(league.settings.data_dir)]) == 0
        with league.client(league.instructor_token) as instructor:
            log = list(reversed(instructor.get("/api/audit", params={"size": 100}).json()["items"]))
            spreadsheet = list(csv.DictReader(io.StringIO(instructor.get("/api/audit.csv").text)))
    events = {e["action"]: e for e in log}  # the last of each
    edits = [e for e in log if e["action"] == "assignment.edit"]
    extensions = [e["details"] for e in log if e["action"] == "assignment.extension"]
    publications = {e["target_id"]: (e["actor_name"], e["details"]) for e in log
                    if e["action"] == "assignment.publish"}
    monkeypatch.delenv("LEAGUE_DATABASE_URL")
    restored_dir = tmp_path / "restored"
    assert main(["restore", str(tmp_path / "league.backup"), "--data-dir", str(restored_dir)]) == 0
    from league.server.db.session import make_engine, make_sessionmaker

    engine = make_engine(f"sqlite:///{restored_dir / 'league.db'}")
    with make_sessionmaker(engine)() as session:
        restored_actions = [e.action for e in session.scalars(select(AuditEvent).order_by(AuditEvent.id))]
        restore = session.scalar(select(AuditEvent).where(AuditEvent.action == "league.restore"))
    engine.dispose()

    assert all(step.status_code < 300 for step in steps), [step.text for step in steps]
    creations = [e for e in log if e["action"] == "assignment.create"]
    assert [(e["target_kind"], e["target_id"]) for e in creations] == [("assignment", hw["id"]),
                                                                      ("assignment", auto["id"])]
    created = creations[0]
    assert created["details"]["before"] == {}
    assert {k: created["details"]["after"][k] for k in ("name", "due_at", "late_until", "late_penalty")} == {
        "name": "hw", "due_at": iso(T1), "late_until": iso(T2), "late_penalty": 0.5}
    assert [(e["target_id"], e["details"]["before"], e["details"]["after"]) for e in edits] == [
        (hw["id"], {"due_at": iso(T1), "late_penalty": 0.5}, {"due_at": iso(T1 + timedelta(hours=1)),
                                                             "late_penalty": 0.8})]
    assert [(e["assignment_id"], e["before"], e["after"]) for e in extensions] == [
        (hw["id"], {"extension_due_at": None}, {"extension_due_at": iso(T2)}),
        (hw["id"], {"extension_due_at": iso(T2)}, {"extension_due_at": None})]
    assert events["assignment.extension"]["target_id"] == student.id
    assert student.name not in str(extensions)
    csv_edit = next(row["details"] for row in spreadsheet if row["action"] == "assignment.edit")
    assert f'before={{"due_at": "{iso(T1)}", "late_penalty": 0.5}}' in csv_edit
    rubric = events["assignment.rubric"]["details"]
    assert rubric["before"] == {"rubric": None} and rubric["after"]["rubric"]["max_points"] == 10
    rerun_event = events["evaluation.rerun"]["details"]
    assert rerun_event["before"]["status"] == "done" and rerun_event["before"]["completed"] == 2
    assert rerun_event["after"]["status"] == "queued" and rerun_event["after"]["evaluation_id"] != \
        rerun_event["before"]["id"]
    assert events["job.cancel"]["target_id"] == rerun_job
    assert (events["job.cancel"]["details"]["before"], events["job.cancel"]["details"]["after"]) == (
        {"status": "queued"}, {"status": "failed"})
    settings = events["settings.evaluation"]["details"]
    assert settings["after"] == {"seed": 7, "episodes": 2} and settings["before"]["seed"] != 7
    published = {"before": {"published_at": None}, "after": {"published_at": iso(T2 + timedelta(seconds=1))}}
    assert publications[hw["id"]] == ("prof", published)
    assert publications[auto["id"]] == ("league server",
                                        {**published, "note": "auto_publish: every final decided and evaluated"})
    backup = events["league.backup"]
    assert (backup["actor_name"], backup["target_kind"]) == ("league CLI", "league")
    assert backup["details"]["rows"]["users"] >= 2  # prof, sue (and the baselines' account)
    assert restored_actions[-1] == "league.restore" and "league.backup" not in restored_actions
    assert restore.actor_name == "league CLI" and restore.details["replaced"] is False
    assert restore.details["rows"] == backup["details"]["rows"]
