"""Deleting a student after everything a course does to their rows (a due time with an extension and
a selection, their frozen final and its private evaluation, publication, a championship, friendly
races), by the API and by `league users delete`, on both backends.

Which rows name a student is read from the models themselves: every foreign key to users.id, and
transitively to the rows reached so (submissions, evaluations, races, ...). The fixture must give
the student a row through each of them (a table added later fails this test until the fixture, and
the erasure, cover it); after the deletion none is left, no column of any table holds their name,
address or file names, the data directory holds no file of theirs (nor, on SQLite, do the database's
files hold any of their bytes), and no answer names them.
"""
from __future__ import annotations

import gzip
import io
import json
import uuid
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from sqlalchemy import LargeBinary, make_url, select, update

from league.server.app import catch_up
from league.server.db import crud
from league.server.db.models import (
    PRIVATE_TRACKS, READY, STUDENT, Assignment, Base, Championship, Evaluation, Job, Race, StudentAssignment,
    Submission, SubmissionProbe, User,
)
from league.server.course.races import create_race
from league.server.storage import BlobStore

from .api.in_process import evaluation_outcome, every_get, in_process_league
from .api_calls import unique
from .backends import BACKENDS
from .race_outcomes import finish_race

DUE = datetime(2030, 3, 8, 23, 59, tzinfo=timezone.utc)
EXTENDED = DUE + timedelta(days=1)
Edge = tuple[str, str, str]  # (table, column, the table it refers to)


def edges_to_users() -> list[Edge]:
    """Every foreign key that leads to users.id: directly, or to a table whose rows do."""
    reached, edges = {"users"}, set()
    while True:
        new = {(table.name, key.parent.name, key.column.table.name) for table in Base.metadata.tables.values()
               for key in table.foreign_keys if key.column.table.name in reached} - edges
        if not new:
            return sorted(edges)
        edges |= new
        reached |= {table for table, _, _ in new}


def rows_naming(session, seed: dict[str, set]) -> dict[Edge, set]:
    """The rows reached from `seed` (table -> primary keys) through each edge, until nothing new is
    reached. A row reached through its own table's key (an account another created) names the
    student, but is not theirs: nothing is followed from it."""
    tables = Base.metadata.tables
    found = {name: set(ids) for name, ids in seed.items()}
    through: dict[Edge, set] = {}
    while True:
        grew = False
        for edge in edges_to_users():
            table, column, referred = edge
            ids = found.get(referred)
            if not ids:
                continue
            key = tables[table].primary_key.columns.values()[0]
            rows = set(session.scalars(select(key).where(tables[table].c[column].in_(ids))))
            if rows - through.get(edge, set()):
                through[edge] = through.get(edge, set()) | rows
                if table != referred and rows - found.get(table, set()):
                    found[table] = found.get(table, set()) | rows
                    grew = True
        if not grew:
            return through


def every_value(session) -> list[tuple[str, str]]:
    """(table, text) for every value of every row of every table; binary values unzipped when gzip."""
    values = []
    for table in Base.metadata.sorted_tables:
        for row in session.execute(select(table)):
            for column, value in zip(table.columns, row):
                if isinstance(column.type, LargeBinary) and value is not None:
                    value = gzip.decompress(value) if value[:2] == b"\x1f\x8b" else value
                    value = value.decode("latin-1")
                values.append((table.name, value if isinstance(value, str) else json.dumps(value, default=str)))
    return values


def model_file(store: BlobStore, marker: str) -> tuple[str, bytes]:
    data = f"model of {marker} {uuid.uuid4().hex}".encode()
    sha256, _ = store.save(io.BytesIO(data), max_bytes=1 << 20)
    return sha256, data


def evaluated_submission(league, session, owner: User, assignment: Assignment, sha256: str, data: bytes) -> int:
    """A ready submission of `assignment` whose public evaluation is queued (finished by the caller)."""
    crud.save_blob(session, sha256=sha256, data=data)
    submission, job = crud.create_submission(session, owner=owner, assignment=assignment,
                                             name=unique(f"{owner.name}-car"), filename="car.onnx", kind="onnx",
                                             sha256=sha256, size=len(data), max_attempts=1)
    submission.status, submission.public, submission.obs_dim, job.status = READY, True, 5, "done"
    settings = assignment.evaluation_settings()
    crud.create_evaluation(session, submission=submission, assignment=assignment, settings=settings,
                           result_key=league_key(settings), max_attempts=1)
    session.flush()
    return submission.id


def league_key(settings: dict) -> str:
    from league.server.course.results import settings_key

    return settings_key(settings)


def queued_jobs(league, submission_ids: list[int], track: str | None = None) -> list[tuple[int, dict]]:
    """The queued evaluation jobs of these submissions, with their settings."""
    with league.sessions() as session:
        rows = session.execute(select(Job.id, Evaluation.settings).join(Evaluation, Job.evaluation_id == Evaluation.id)
                               .where(Evaluation.submission_id.in_(submission_ids), Job.status == "queued",
                                      *([Evaluation.track == track] if track else [])))
        return [(job_id, settings) for job_id, settings in rows]


def build_course(league, clock) -> dict:
    """Dora, with a row through every edge; Ann and Bob, who raced with her."""
    store = BlobStore(league.settings.data_dir)
    clock.set(DUE - timedelta(hours=1))
    with league.client(league.instructor_token) as instructor:
        hw = instructor.post("/api/assignments", json={"name": unique("hw"), "episodes": 3,
                                                       "due_at": DUE.isoformat()}).json()
    with league.sessions.begin() as session:
        course = crud.first_course(session)
        people = {n: crud.create_user(session, name=unique(n), role=STUDENT, course=course,
                                      email=f"{n}-{uuid.uuid4().hex[:6]}@uni.example",
                                      student_id=uuid.uuid4().hex[:9]) for n in ("dora", "ann", "bob")}
        users = {n: session.get(User, u.id) for n, (u, _) in people.items()}
        users["dora"].display_name = unique("Speedy")
        assignment = session.get(Assignment, hw["id"])
        shared, shared_data = model_file(store, "shared")
        own, own_data = model_file(store, users["dora"].name)
        ids = {"dora": [evaluated_submission(league, session, users["dora"], assignment, shared, shared_data),
                        evaluated_submission(league, session, users["dora"], assignment, own, own_data)],
               "ann": evaluated_submission(league, session, users["ann"], assignment, shared, shared_data),
               "bob": evaluated_submission(league, session, users["bob"], assignment, *model_file(store, "bob"))}
        # the rows a student never makes through the API, but which name them all the same
        crud.create_user(session, name=unique("made-by-dora"), role=STUDENT, course=course, created_by=users["dora"])
        session.add(SubmissionProbe(submission_id=ids["dora"][1], probe_key="secret-test",  # a secret probe
                                    actions=bytes(64 * 2 * 4)))
        secrets_ = [users["dora"].name, users["dora"].email, users["dora"].student_id, users["dora"].display_name,
                    *(session.get(Submission, i).name for i in ids["dora"])]
        dora = users["dora"].id
    tokens = {n: token for n, (_, token) in people.items()}
    everyone = [*ids["dora"], ids["ann"], ids["bob"]]
    for job_id, _ in queued_jobs(league, everyone):
        league.finish_job(job_id, evaluation_outcome(2))

    with league.client(league.instructor_token) as instructor:
        assert instructor.put(f"/api/assignments/{hw['id']}/extensions/{dora}",
                              json={"due_at": EXTENDED.isoformat()}).status_code == 200
    with league.client(tokens["dora"]) as client:
        assert client.post(f"/api/assignments/{hw['id']}/selection",
                           json={"submission_id": ids["dora"][0]}).status_code == 200
    with league.sessions.begin() as session:
        users = {n: session.get(User, u.id) for n, (u, _) in people.items()}
        friendly, _ = create_race(session, entrants=[session.get(Submission, ids["dora"][0]),
                                                     session.get(Submission, ids["ann"])], seed=1, env_options={},
                                  created_by=users["dora"], course_id=users["dora"].course_id, max_attempts=1)
        alone, _ = create_race(session, entrants=[session.get(Submission, i) for i in ids["dora"]], seed=2,
                               env_options={}, created_by=users["dora"], course_id=users["dora"].course_id,
                               max_attempts=1)
        races = {"friendly": friendly.id, "alone": alone.id}
    finish_race(league, races["friendly"], [ids["dora"][0], ids["ann"]])
    finish_race(league, races["alone"], ids["dora"])

    clock.set(EXTENDED + timedelta(seconds=1))  # every due time passed: the finals freeze, the private tests run
    catch_up(league.app.state.services)
    for job_id, settings in queued_jobs(league, everyone, PRIVATE_TRACKS):
        league.finish_job(job_id, evaluation_outcome(3, settings=settings))
    with league.client(league.instructor_token) as instructor:
        assert instructor.post(f"/api/assignments/{hw['id']}/publish").status_code == 200
        cup = instructor.post("/api/championships", json={"name": unique("cup"), "heat_size": 3, "seed": 5,
                                                          "include_baselines": False}).json()
        heat = instructor.post(f"/api/championships/{cup['id']}/rounds").json()["race_ids"][0]
    with league.sessions.begin() as session:
        entrants = [e["submission_id"] for e in session.get(Race, heat).entrants]
        session.execute(update(Championship).where(Championship.id == cup["id"]).values(created_by_id=dora))
    finish_race(league, heat, entrants)
    return {"hw": hw, "dora": dora, "ids": ids, "tokens": tokens, "races": races, "cup": cup["id"],
            "secrets": secrets_, "shared": shared, "own": own, "own_data": own_data}


def delete(league, kind: str, course: dict, tmp_path: Path, monkeypatch) -> None:
    if kind == "api":
        with league.client(league.instructor_token) as instructor:
            answer = instructor.delete(f"/api/users/{course['dora']}")
        assert answer.status_code == 204, answer.text
        return
    from league.server.cli import main

    monkeypatch.setenv("LEAGUE_DATABASE_URL", league.settings.database_url)
    name = course["secrets"][0]
    assert main(["users", "delete", name, "--yes", "--data-dir", str(league.settings.data_dir)]) == 0


@pytest.mark.parametrize("how", ["api", "cli"])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_student_with_a_row_of_every_kind_is_erased_after_due_times_publication_and_championships(
        backend, how, tmp_path, monkeypatch):
    with in_process_league(backend, tmp_path, bootstrap=False) as league:
        clock = league.app.state.services.clock
        course = build_course(league, clock)
        dora, ids = course["dora"], course["ids"]
        own_submissions = {"submissions": set(ids["dora"])}
        with league.sessions() as session:
            own_submissions["evaluations"] = set(session.scalars(
                select(Evaluation.id).where(Evaluation.submission_id.in_(ids["dora"]))))
            before = rows_naming(session, {"users": {dora}})
            final = session.scalar(select(StudentAssignment).where(StudentAssignment.user_id == dora))
            named_before = [table for table, text in every_value(session)
                            if any(secret in text for secret in course["secrets"])]
        missing = [edge for edge in edges_to_users() if not before.get(edge)]
        assert not missing, f"the fixture gives the student no row through {missing}: add one (and erase it)"
        assert final.final_at is not None and final.final_evaluation_id is not None  # after their due time
        assert final.extension_due_at is not None and final.selected_submission_id == ids["dora"][0]
        assert {"users", "submissions", "races", "race_replays"} <= set(named_before)  # the search finds them

        delete(league, how, course, tmp_path, monkeypatch)

        with league.sessions() as session:
            assert session.get(User, dora) is None
            left = {edge: rows for edge, rows in rows_naming(session, {"users": {dora}, **own_submissions}).items()
                    if rows}
            for table, ids_ in own_submissions.items():
                key = Base.metadata.tables[table].c.id
                assert list(session.scalars(select(key).where(key.in_(ids_)))) == [], table
            named = sorted({(table, secret) for table, text in every_value(session)
                            for secret in course["secrets"] if secret in text})
            kept = session.get(Race, course["races"]["friendly"])
            assert session.get(Race, course["races"]["alone"]) is None
        assert left == {}
        assert named == []
        if backend == "sqlite":  # nor in the file: the rows were overwritten, the write-ahead log emptied
            database = Path(make_url(league.settings.database_url).database)
            for path in database.parent.glob(f"{database.name}*"):
                content = path.read_bytes()
                assert course["own_data"] not in content, path
                assert [s for s in course["secrets"] if s.encode() in content] == [], path
        assert [e["submission_id"] for e in kept.entrants] == [-ids["dora"][0], ids["ann"]]

        # the data directory: her own model file is gone, the one Ann uploaded too stays
        store = BlobStore(league.settings.data_dir)
        assert not store.path(course["own"]).exists() and store.path(course["shared"]).exists()
        for path in Path(league.settings.data_dir).rglob("*"):
            if path.is_file():
                content = path.read_bytes()
                assert course["own_data"] not in content, path
                assert not any(secret.encode() in content for secret in course["secrets"]), path

        # every answer, to another student and to the instructor
        with league.sessions() as session:
            race_ids = list(session.scalars(select(Race.id)))
            assignment_ids = list(session.scalars(select(Assignment.id)))
        submissions = [ids["ann"], ids["bob"], *ids["dora"]]
        schema_ids = {"race_id": race_ids, "championship_id": [course["cup"]], "number": [1],
                      "assignment_id": assignment_ids, "submission_id": submissions, "filename": ["none.whl"]}
        urls = {url for url in every_get(league.app, schema_ids) if not url.startswith("/api/package")}
        urls |= {"/api/races?size=100", "/api/leaderboard?size=100", "/api/submissions?all=true",
                 "/api/jobs?limit=1000", "/api/audit?size=100", f"/api/assignments/{course['hw']['id']}/grades",
                 f"/api/assignments/{course['hw']['id']}/board?board=private&size=100",
                 f"/api/assignments/{course['hw']['id']}/board.csv?board=private"}
        for token in (course["tokens"]["bob"], league.instructor_token):
            with league.client(token) as client:
                for url in sorted(urls):
                    response = client.get(url)
                    degraded = url == "/api/health" and response.json()["status"] == "degraded"  # no worker here
                    assert response.status_code < 500 or degraded, (url, response.text)
                    assert not [s for s in course["secrets"] if s in response.text], url
