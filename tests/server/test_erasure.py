"""Deleting a student (league.server.course.erasure, DELETE /api/users/{id}, `league users delete`): their
data gone from every answer a student or an instructor can read, others' races and standings
intact (same points), the audit log naming the deletion by id only."""
from __future__ import annotations

import gzip
import json
import re
from pathlib import Path

import pytest
from sqlalchemy import func, select

from league.server.db import crud
from league.server.db.models import (
    DELETED, DONE, READY, STUDENT, Assignment, AuditEvent, Blob, Evaluation, Job, Race, RaceReplay, Submission, User,
)
from league.server.course.races import create_race
from league.server.jobs.race import car_name

from .api.in_process import every_get, in_process_league
from .api_calls import unique
from .backends import BACKENDS
from .race_outcomes import finish_race

CONTRACT = Path(__file__).resolve().parents[2] / "docs" / "CONTRACT.md"


def ready_submission(session, owner: User, sha256: str, public: bool = False) -> Submission:
    """A ready submission whose jobs are over, its file kept in `blobs`."""
    crud.save_blob(session, sha256=sha256, data=b"model " + sha256.encode())
    submission, job = crud.create_submission(session, owner=owner, name=unique(f"{owner.name}-agent"),
                                             filename="a.onnx", kind="onnx", sha256=sha256, size=7, max_attempts=1)
    submission.status, submission.public, submission.obs_dim, job.status = READY, public, 5, DONE
    assignment = crud.default_assignment(session, course_id=owner.course_id)
    evaluation, eval_job = crud.create_evaluation(session, submission=submission, assignment=assignment,
                                                  settings={"seed": 0, "episodes": 3, "env_options": {}},
                                                  result_key="k", max_attempts=1)
    evaluation.status, evaluation.completed, evaluation.episodes_total, eval_job.status = DONE, 2, 3, DONE
    evaluation.mean_return, evaluation.mean_steps, evaluation.mean_speed = 1.0, 10.0, 0.3
    session.flush()
    return submission


def contract_get_paths() -> list[str]:
    """Every GET route docs/CONTRACT.md names, as written (with {id}, {number}, {filename})."""
    paths = set(re.findall(r"GET\s+(/api/[^\s`?]+)", CONTRACT.read_text()))
    return sorted(p for p in paths if "{filename}" not in p)  # the package's files hold no names


def filled(path: str, ids: dict[str, list[int]]) -> list[str]:
    """`path` with each placeholder filled with every id of its kind."""
    if "{id}" not in path:
        return [path]
    kind = path.split("/")[2]  # races, submissions, championships
    return [path.replace("{id}", str(i)).replace("{number}", "1") for i in ids[kind]]


@pytest.mark.parametrize("kind", BACKENDS)
def test_a_deleted_student_is_gone_everywhere_and_others_keep_their_results(kind, tmp_path):
    with in_process_league(kind, tmp_path, bootstrap=False) as league:
        with league.sessions.begin() as session:
            course = crud.first_course(session)
            people = {n: crud.create_user(session, name=unique(n), role=STUDENT, course=course) for n in
                      ("dora", "ann", "bob")}
            users = {n: session.get(User, u.id) for n, (u, _) in people.items()}
            shared, own = "a" * 64, "b" * 64  # dora's first file is also ann's: it stays
            dora_1 = ready_submission(session, users["dora"], shared)
            dora_2 = ready_submission(session, users["dora"], own)
            ann_1 = ready_submission(session, users["ann"], shared, public=True)
            bob_1 = ready_submission(session, users["bob"], "c" * 64)
            friendly, _ = create_race(session, entrants=[dora_1, ann_1], seed=1, env_options={},
                                      created_by=users["dora"], course_id=course.id, max_attempts=1)
            alone, _ = create_race(session, entrants=[dora_1, dora_2], seed=2, env_options={},
                                   created_by=users["dora"], course_id=course.id, max_attempts=1)
            ids = {"dora": [dora_1.id, dora_2.id], "ann": ann_1.id, "bob": bob_1.id, "friendly": friendly.id,
                   "alone": alone.id}
            secret_names = [users["dora"].name, dora_1.name, dora_2.name]
            dora_id = users["dora"].id
        tokens = {n: token for n, (_, token) in people.items()}
        finish_race(league, ids["friendly"], [ids["dora"][0], ids["ann"]])
        finish_race(league, ids["alone"], ids["dora"])

        with league.client(league.instructor_token) as instructor:
            cup = instructor.post("/api/championships", json={"name": "cup", "heat_size": 3, "seed": 5,
                                                              "include_baselines": False}).json()
            heat = instructor.post(f"/api/championships/{cup['id']}/rounds").json()["race_ids"][0]
            finish_race(league, heat, [ids["ann"], ids["dora"][1], ids["bob"]])
            second = instructor.post(f"/api/championships/{cup['id']}/rounds").json()["race_ids"][0]
            refused = instructor.delete(f"/api/users/{dora_id}")  # round 2 still to race with her car
            finish_race(league, second, [ids["dora"][1], ids["bob"], ids["ann"]])
            standings_before = instructor.get(f"/api/championships/{cup['id']}/standings").json()["items"]
            with league.client(tokens["ann"]) as ann:
                by_student = ann.delete(f"/api/users/{dora_id}")
            deleted = instructor.delete(f"/api/users/{dora_id}")
            standings = instructor.get(f"/api/championships/{cup['id']}/standings").json()["items"]
            log = instructor.get(f"/api/races/{ids['friendly']}/log").text
            audit = instructor.get("/api/audit").json()["items"]

        assert refused.status_code == 409 and "still to race" in refused.json()["detail"]
        assert by_student.status_code == 403
        assert deleted.status_code == 204, deleted.text

        # others' standings intact: the same points, wins and ratings; dora's car a deleted student's
        def points(rows):
            return [(r["rank"], abs(r["submission_id"]), r["points"], r["wins"], r["rating"]) for r in rows]
        assert points(standings) == points(standings_before)
        mine = [r for r in standings if r["submission_id"] < 0]
        assert [(r["submission_id"], r["name"], r["owner"]) for r in mine] == [(-ids["dora"][1], DELETED, DELETED)]
        assert f"== {car_name({'name': DELETED, 'owner': DELETED})} ==" not in log and "hello from" in log
        assert audit[0]["action"] == "user.delete" and audit[0]["target_id"] == dora_id
        assert audit[0]["details"]["submissions"] == 2 and audit[0]["details"]["races_deleted"] == 1

        # walk every GET route of the contract as another student and as the instructor
        with league.sessions() as session:
            race_ids = list(session.scalars(select(Race.id)))
            assignment_ids = list(session.scalars(select(Assignment.id)))
        everything = {"races": race_ids, "championships": [cup["id"]], "assignments": assignment_ids,
                      "submissions": [ids["ann"], ids["bob"], *ids["dora"]]}
        schema_ids = {"race_id": race_ids, "championship_id": [cup["id"]], "number": [1, 2],
                      "assignment_id": assignment_ids,
                      "submission_id": everything["submissions"], "filename": ["none.whl"]}
        urls = {url for path in contract_get_paths() for url in filled(path, everything)}
        urls |= {url for url in every_get(league.app, schema_ids)  # every GET route the app has, /metrics too
                 if not url.startswith("/api/package")}  # (the package's files hold no names; built on request)
        urls |= {"/api/races?size=100", "/api/leaderboard?size=100",
                 f"/api/championships/{cup['id']}/standings?size=100",
                 "/api/submissions?all=true", "/api/jobs?limit=1000", "/api/audit?size=100"}
        bodies = []
        for token in (tokens["bob"], league.instructor_token):
            with league.client(token) as client:
                for url in sorted(urls):
                    response = client.get(url)
                    assert response.status_code < 500 or url == "/api/health", (url, response.text)  # (no worker)
                    bodies.append((url, response.text))
        assert ids["alone"] not in race_ids and ids["friendly"] in race_ids
        assert len(bodies) > 60
        for url, body in bodies:
            for name in secret_names:
                assert name not in body, (url, name)
        with league.client(tokens["dora"]) as dora:
            assert dora.get("/api/users/me").status_code == 401

        with league.sessions() as session:
            assert session.get(User, dora_id) is None
            assert session.scalar(select(func.count()).select_from(Submission)
                                  .where(Submission.id.in_(ids["dora"]))) == 0
            assert session.scalar(select(func.count()).select_from(Evaluation)
                                  .where(Evaluation.submission_id.in_(ids["dora"]))) == 0
            assert session.scalar(select(func.count()).select_from(Job)
                                  .where(Job.submission_id.in_(ids["dora"]) | (Job.owner_id == dora_id))) == 0
            assert set(session.scalars(select(Blob.sha256))) >= {shared} and session.get(Blob, own) is None
            replay = gzip.decompress(session.get(RaceReplay, ids["friendly"]).data).decode()
            kept = session.get(Race, ids["friendly"])
            events = list(session.scalars(select(AuditEvent)))
        assert all(name not in replay for name in secret_names) and DELETED in replay
        assert [e["owner"] for e in kept.entrants] == [DELETED, users["ann"].name]
        assert [(r["position"], r["submission_id"]) for r in kept.classification] == \
            [(1, -ids["dora"][0]), (2, ids["ann"])]
        assert all(name not in json.dumps(e.details) for e in events for name in secret_names)


def test_league_users_delete_asks_and_erases(tmp_path):
    """The CLI deletes only when told to (--yes, or the name typed), and records it in the audit log."""
    from league.server.cli import main

    data = tmp_path / "data"
    assert main(["init", "--data-dir", str(data)]) == 0
    assert main(["users", "add", "erin", "--data-dir", str(data)]) == 0
    assert main(["users", "delete", "erin", "--data-dir", str(data)]) == 1  # no terminal to confirm on
    assert main(["users", "delete", "erin", "--yes", "--data-dir", str(data)]) == 0
    assert main(["users", "delete", "erin", "--yes", "--data-dir", str(data)]) == 1  # no such user now
    from league.server.db.session import make_engine, make_sessionmaker

    engine = make_engine(f"sqlite:///{data / 'league.db'}")
    with make_sessionmaker(engine)() as session:
        assert crud.user_by_name(session, name="erin") is None
        actions = [(e.action, e.actor_name) for e in session.scalars(select(AuditEvent).order_by(AuditEvent.id))]
    engine.dispose()
    assert actions == [("user.create", "league CLI"), ("user.delete", "league CLI")]


def test_an_upload_or_race_of_a_student_deleted_meanwhile_is_refused(tmp_path):
    """A request whose token was accepted just before the deletion finds the account gone when it
    takes the student's row (uploads and races do, to check their quotas): 401, not a broken row."""
    from fastapi import HTTPException

    from league.server.api.deps import lock_account
    from league.server.course.erasure import delete_student

    with in_process_league("sqlite", tmp_path, bootstrap=False) as league:
        student, _ = league.user("gil")
        with league.sessions.begin() as session:
            delete_student(session, user=session.get(User, student.id))
        with league.sessions() as session, pytest.raises(HTTPException) as refusal:
            lock_account(session, student)
    assert (refusal.value.status_code, refusal.value.detail) == (401, "this account was deleted")
