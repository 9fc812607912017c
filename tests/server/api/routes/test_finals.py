"""Finals under a backlog, on the real app and database (both backends), the server's clock held by
the test: students upload just before the due time while no worker runs; the due time passes (the
API's start or a reaper pass freezes the finals with their candidates); then the queue's jobs run
(finished through their leases, as a worker finishes them). Every student who uploaded in time gets
their final, its private evaluation and a grade; the assignment publishes itself only then; a result
that changes after the publication changes the grade, which says so."""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from datetime import datetime, timedelta, timezone

import pytest

from league.server.app import catch_up
from league.server.db import crud
from league.server.db.models import (
    DONE, EVALUATE, PRIVATE_TRACKS, PUBLIC_TRACKS, QUEUED, VALIDATE, Assignment, Evaluation, Job, StudentAssignment,
    Submission,
)
from league.server.jobs.runner import close_due_now
from league.validation.report import ValidationReport

from ...api_calls import unique
from ...backends import BACKENDS
from ..in_process import evaluation_outcome, in_process_league

# in the past of the real clock too: a worker's own passes (which read it) may publish
DUE = datetime(2001, 6, 1, 12, 0, tzinfo=timezone.utc)
SECOND = timedelta(seconds=1)
EPISODES = 4
RUBRIC = {"kind": "points", "max_points": 10, "completed": {"kind": "linear", "points": 10}}


@pytest.fixture(scope="module", params=BACKENDS)
def league(request, tmp_path_factory):
    """A league of its own: these tests move its clock, and its due-time passes close every assignment."""
    with in_process_league(request.param, tmp_path_factory.mktemp(f"finals-{request.param}"),
                           quota_per_day=1000, max_jobs_in_flight=100) as league_:
        yield league_


@pytest.fixture(autouse=True)
def clock(league):
    yield league.app.state.services.clock
    league.app.state.services.clock.set(None)


def upload(client, assignment: str) -> int:
    response = client.post("/api/submissions", files={"file": ("agent.onnx", b"an agent")},
                           data={"assignment": assignment})
    assert response.status_code == 201, response.text
    return response.json()["id"]


def queued(league, kind: str, track: str | None = None) -> dict[int, int]:
    """The queued jobs of `kind` (of evaluations of `track`): submission id -> job id."""
    with league.sessions() as session:
        query = crud.select(Job.submission_id, Job.id).where(Job.kind == kind, Job.status == QUEUED)
        if track is not None:
            query = query.join(Evaluation, Job.evaluation_id == Evaluation.id).where(Evaluation.track == track)
        return dict(session.execute(query).all())


def settings_of(league, assignment_id: int, track: str) -> dict:
    with league.sessions() as session:
        assignment = session.get(Assignment, assignment_id)
        return assignment.private_settings() if track == PRIVATE_TRACKS else assignment.evaluation_settings()


def final_rows(league, assignment_id: int) -> dict[int, StudentAssignment]:
    with league.sessions() as session:
        rows = crud.student_assignments(session, assignment_id=assignment_id)
        session.expunge_all()
        return rows


def grades(instructor, assignment_id: int) -> dict[str, dict]:
    response = instructor.get(f"/api/assignments/{assignment_id}/grades")
    assert response.status_code == 200, response.text
    return {row["name"]: row for row in response.json()["rows"] if row["role"] == "student"}


def published_at(instructor, assignment_id: int) -> str | None:
    return instructor.get(f"/api/assignments/{assignment_id}").json()["published_at"]


def test_uploads_queued_at_the_due_time_become_finals_graded_before_the_assignment_publishes_itself(league, clock,
                                                                                                     monkeypatch,
                                                                                                     capsys):
    """ann uploads twice, bob twice (one is rejected), cy once (rejected), dee never; all within the
    last minute, no worker running. After the due time: three finals wait, none is "no final" but
    cy's and dee's; the worker's jobs then decide them (ann's best, bob's valid one), evaluate them on
    the private tracks, and the assignment publishes itself once the last is done."""
    instructor = league.client(league.instructor_token)
    name = unique("rush")
    created = instructor.post("/api/assignments", json={"name": name, "episodes": EPISODES, "due_at": DUE.isoformat(),
                                                        "auto_publish": True})
    assert created.status_code == 201, created.text
    hw = created.json()["id"]
    assert instructor.put(f"/api/assignments/{hw}/rubric", json=RUBRIC).status_code == 200
    students = {key: league.student(key) for key in ("ann", "bob", "cy", "dee")}
    user = {key: students[key][0] for key in students}
    names = {key: students[key][0].name for key in students}

    clock.set(DUE - 60 * SECOND)
    uploads = {"ann": [upload(students["ann"][1], name), upload(students["ann"][1], name)],
               "bob": [upload(students["bob"][1], name), upload(students["bob"][1], name)],
               "cy": [upload(students["cy"][1], name)]}
    clock.set(DUE + SECOND)  # no worker ran: every upload still waits for its validation
    assert catch_up(league.app.state.services) == []  # frozen, nothing to evaluate privately yet
    assert catch_up(league.app.state.services) == []  # idempotent
    rows = final_rows(league, hw)
    for key, ids in uploads.items():
        row = rows[user[key].id]
        assert (row.final_at, row.final_candidates, row.final_decided_at) == (DUE, ids, None)
    assert rows[user["dee"].id].final_candidates == [] and rows[user["dee"].id].final_decided_at is not None
    table = grades(instructor, hw)
    assert {key: table[names[key]]["status"] for key in names} == {
        "ann": "pending", "bob": "pending", "cy": "pending", "dee": "no final"}
    assert [table[names[key]]["points"] for key in ("ann", "bob", "cy")] == [None, None, None]
    own = students["ann"][1].get(f"/api/assignments/{hw}").json()["final"]
    assert (own["frozen_at"], own["decided"]) == ("2001-06-01T12:00:00+00:00", False)
    assert published_at(instructor, hw) is None

    # the worker starts: the validations (bob's first and cy's upload are rejected), then the public evaluations
    validations = queued(league, VALIDATE)
    for submission_id in sorted(uploads["ann"] + uploads["bob"] + uploads["cy"]):
        ok = submission_id not in (uploads["bob"][0], uploads["cy"][0])
        report = ValidationReport(True, 5, None, "validated in a test") if ok else \
            ValidationReport(False, None, "not an ONNX model", "")
        league.finish_job(validations[submission_id], report)
    table = grades(instructor, hw)
    assert table[names["cy"]]["status"] == "no final"  # their only candidate dropped out: decided at once
    assert (table[names["ann"]]["status"], table[names["bob"]]["status"]) == ("pending", "pending")
    public = queued(league, EVALUATE, PUBLIC_TRACKS)
    everyone = {i for ids in uploads.values() for i in ids}  # (the baselines' jobs wait too)
    assert set(public) & everyone == {*uploads["ann"], uploads["bob"][1]}
    figures = {uploads["ann"][0]: 3, uploads["ann"][1]: 2, uploads["bob"][1]: 1}  # ann's first is her best
    for submission_id, completed in figures.items():
        assert published_at(instructor, hw) is None
        league.finish_job(public[submission_id],
                          evaluation_outcome(completed, EPISODES, settings_of(league, hw, PUBLIC_TRACKS)))

    # each final decided as its last candidate's evaluation ended, and its private evaluation queued
    rows = final_rows(league, hw)
    decided = {key: rows[user[key].id].final_submission_id for key in ("ann", "bob", "cy", "dee")}
    assert decided == {"ann": uploads["ann"][0], "bob": uploads["bob"][1], "cy": None, "dee": None}
    private = queued(league, EVALUATE, PRIVATE_TRACKS)
    assert set(private) & everyone == {uploads["ann"][0], uploads["bob"][1]}
    assert catch_up(league.app.state.services) == []  # nothing more to decide, nothing to publish yet
    assert published_at(instructor, hw) is None and grades(instructor, hw)[names["ann"]]["status"] == "pending"
    own = students["ann"][1].get(f"/api/assignments/{hw}").json()["final"]
    assert (own["submission_id"], own["decided"]) == (uploads["ann"][0], True)

    private_settings = settings_of(league, hw, PRIVATE_TRACKS)
    league.finish_job(private[uploads["ann"][0]], evaluation_outcome(4, EPISODES, private_settings))
    assert published_at(instructor, hw) is None  # bob's private evaluation still runs
    league.finish_job(private[uploads["bob"][1]], evaluation_outcome(2, EPISODES, private_settings))
    assert published_at(instructor, hw) is not None  # at once, as the last private evaluation ended
    table = grades(instructor, hw)
    assert {key: (table[names[key]]["status"], table[names[key]]["points"]) for key in names} == {
        "ann": ("graded", 10.0), "bob": ("graded", 5.0), "cy": ("no final", 0.0), "dee": ("no final", 0.0)}
    assert not any(row["revised"] for row in table.values())
    mine = students["bob"][1].get(f"/api/assignments/{hw}/grades/me").json()
    assert (mine["status"], mine["points"], mine["revised"], mine["note"]) == ("graded", 5.0, False, None)

    # after the publication the private tracks change (fewer episodes): the grades follow and say so
    changed = instructor.patch(f"/api/assignments/{hw}", json={"episodes": EPISODES - 1})
    assert changed.status_code == 200, changed.text
    table = grades(instructor, hw)
    assert (table[names["ann"]]["status"], table[names["ann"]]["points"], table[names["ann"]]["revised"]) == (
        "stale", None, True)
    assert instructor.put(f"/api/assignments/{hw}/rubric", json=RUBRIC).status_code == 200  # queues the re-runs
    again = queued(league, EVALUATE, PRIVATE_TRACKS)
    assert set(again) & everyone == {uploads["ann"][0], uploads["bob"][1]}
    private_settings = settings_of(league, hw, PRIVATE_TRACKS)
    league.finish_job(again[uploads["ann"][0]], evaluation_outcome(3, EPISODES - 1, private_settings))
    league.finish_job(again[uploads["bob"][1]], evaluation_outcome(3, EPISODES - 1, private_settings))
    table = grades(instructor, hw)
    assert {key: (table[names[key]]["status"], table[names[key]]["points"], table[names[key]]["revised"])
            for key in names} == {"ann": ("graded", 10.0, True), "bob": ("graded", 10.0, True),
                                  "cy": ("no final", 0.0, False), "dee": ("no final", 0.0, False)}
    mine = students["bob"][1].get(f"/api/assignments/{hw}/grades/me").json()
    assert (mine["points"], mine["revised"]) == (10.0, True)
    assert "completed 2/4" in mine["note"]  # what it was at the publication
    csv_text = instructor.get(f"/api/assignments/{hw}/grades.csv").text
    assert csv_text.splitlines()[0].endswith(",note") and mine["note"] in csv_text
    assert f"changed since the publication: {mine['note']}" in my_grade_in_the_terminal(
        league, students["bob"][1], name, monkeypatch, capsys)


def my_grade_in_the_terminal(league, client, assignment: str, monkeypatch, capsys) -> str:
    """`league grades NAME` as the client's student, against the app itself (the CLI's HTTP client
    given the app's transport)."""
    from league.client.api import Api
    from league.cli import main

    def api_on_the_app(self, conn, timeout: float = 60):
        self.conn, self.http = conn, league.client(conn.token)

    monkeypatch.setattr(Api, "__init__", api_on_the_app)
    monkeypatch.setenv("LEAGUE_SERVER", "http://testserver")
    monkeypatch.setenv("LEAGUE_TOKEN", client.headers["Authorization"].removeprefix("Bearer "))
    capsys.readouterr()
    assert main(["grades", assignment]) == 0
    return capsys.readouterr().out


def test_a_selected_final_is_decided_at_the_due_time_and_a_late_evaluation_never_makes_a_no_final(league, clock):
    """A student who selected a ready submission has it as their final at once, whatever else of
    theirs is queued; an instructor who publishes by hand before the last final is decided sees
    that grade pending, then graded "after the publication"."""
    instructor = league.client(league.instructor_token)
    name = unique("manual")
    due = DUE + timedelta(days=1)
    created = instructor.post("/api/assignments", json={"name": name, "episodes": EPISODES, "due_at": due.isoformat()})
    hw = created.json()["id"]
    assert instructor.put(f"/api/assignments/{hw}/rubric", json=RUBRIC).status_code == 200
    chooser_user, chooser = league.student("chooser")
    slow_user, slow = league.student("slow")
    clock.set(due - 60 * SECOND)
    chosen = upload(chooser, name)
    league.finish_job(queued(league, VALIDATE)[chosen], ValidationReport(True, 5, None, "validated in a test"))
    assert chooser.post(f"/api/assignments/{hw}/selection", json={"submission_id": chosen}).status_code == 200
    upload(chooser, name)  # still queued at the due time: the selection wins all the same
    late = upload(slow, name)
    clock.set(due + SECOND)
    jobs = catch_up(league.app.state.services)
    private = queued(league, EVALUATE, PRIVATE_TRACKS)
    assert private.get(chosen) in jobs and late not in private
    assert instructor.post(f"/api/assignments/{hw}/publish").status_code == 200  # by hand, before all is done
    table = grades(instructor, hw)
    assert (table[slow_user.name]["status"], table[slow_user.name]["points"]) == ("pending", None)

    league.finish_job(queued(league, VALIDATE)[late], ValidationReport(True, 5, None, "validated in a test"))
    league.finish_job(queued(league, EVALUATE, PUBLIC_TRACKS)[late],
                      evaluation_outcome(1, EPISODES, settings_of(league, hw, PUBLIC_TRACKS)))
    league.finish_job(queued(league, EVALUATE, PRIVATE_TRACKS)[late],
                      evaluation_outcome(1, EPISODES, settings_of(league, hw, PRIVATE_TRACKS)))
    league.finish_job(private[chosen], evaluation_outcome(4, EPISODES, settings_of(league, hw, PRIVATE_TRACKS)))
    table = grades(instructor, hw)
    assert (table[slow_user.name]["status"], table[slow_user.name]["points"], table[slow_user.name]["revised"]) == (
        "graded", 2.5, True)
    assert table[slow_user.name]["note"].startswith("graded after the publication")
    assert table[chooser_user.name]["submission_id"] == chosen
    with league.sessions() as session:
        assert session.get(Submission, late).status == "ready"


def test_due_time_passes_of_several_processes_at_once_decide_each_final_once(league, clock):
    """Four passes at the same moment (workers' reapers, an API starting) over finals whose candidates
    have all just been evaluated: each final is decided once, with one private evaluation; a pass that
    gave way to another leaves nothing undone."""
    instructor = league.client(league.instructor_token)
    name, due = unique("race"), DUE + timedelta(days=2)
    created = instructor.post("/api/assignments", json={"name": name, "episodes": EPISODES, "due_at": due.isoformat()})
    assert created.status_code == 201, created.text
    clock.set(due - 60 * SECOND)
    ids = [upload(league.student("racer")[1], name) for _ in range(6)]
    validations = queued(league, VALIDATE)
    for submission_id in ids:
        league.finish_job(validations[submission_id], ValidationReport(True, 5, None, "validated in a test"))
    clock.set(due + SECOND)
    assert catch_up(league.app.state.services) == []  # frozen: every public evaluation still queued
    public = queued(league, EVALUATE, PUBLIC_TRACKS)
    with league.sessions.begin() as session:  # they end without their jobs' own passes (as an older worker's)
        for k, submission_id in enumerate(ids):
            job = session.get(Job, public[submission_id])
            evaluation = session.get(Evaluation, job.evaluation_id)
            job.status, evaluation.status, evaluation.episodes_total = DONE, DONE, EPISODES
            evaluation.completed, evaluation.mean_return = 1 + k % EPISODES, float(k)

    barrier = threading.Barrier(4)

    def one_pass(_) -> list[int]:
        barrier.wait()
        return close_due_now(league.sessions, league.app.state.services.queue, max_attempts=1, now=due + 2 * SECOND)

    with ThreadPoolExecutor(4) as pool:
        queued_by_passes = [job_id for jobs in pool.map(one_pass, range(4)) for job_id in jobs]
    catch_up(league.app.state.services)  # the next pass: what every pass gave way on, if any
    with league.sessions() as session:
        hw = session.scalar(crud.select(Assignment.id).where(Assignment.name == name))
        private = session.execute(crud.select(Evaluation.submission_id, Job.id).join(
            Job, Job.evaluation_id == Evaluation.id).where(Evaluation.assignment_id == hw,
                                                           Evaluation.track == PRIVATE_TRACKS)).all()
    assert sorted(submission_id for submission_id, _ in private) == sorted(ids)  # each once
    assert len(set(queued_by_passes)) == len(queued_by_passes) and set(queued_by_passes) <= {j for _, j in private}
    assert all(row.final_submission_id in ids for row in final_rows(league, hw).values()
               if row.final_candidates)
