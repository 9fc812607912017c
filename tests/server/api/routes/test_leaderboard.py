"""The public course leaderboard over real HTTP (ratings before and after a round: see
test_championships.py, whose league has no response cache)."""
from __future__ import annotations

import csv
import io
import time
import uuid

import pytest

from league.server.db.models import INSTRUCTOR, Submission

from ... import model_factory as mf
from ...conftest import (
    add_user_in_new_course, baseline_submission, create_student, fresh_backend, make_server, upload_ready, wait_for,
)

CACHE_S = 2.0  # the default LEAGUE_PUBLIC_CACHE_S


def unique(name: str) -> str:
    return f"{name}-{uuid.uuid4().hex[:6]}"


def score(row: dict) -> tuple[float, float]:
    return (row["completed"] / row["episodes"], row["mean_return"])


def test_the_leaderboard_shows_each_students_best_agent_and_the_baselines(league_server, models, tmp_path):
    name = unique("lena")
    student = create_student(league_server, name)
    better = upload_ready(student, models["onnx"], name="better")
    worse = upload_ready(student, mf.onnx_nan_when_straight(tmp_path / "nan.onnx"), name="worse")  # the latest
    with league_server.client(add_user_in_new_course(league_server, unique("elsewhere"), unique("course"))) as other:
        outsider = upload_ready(other, models["heuristic_onnx"])
    baseline = baseline_submission(league_server)
    time.sleep(CACHE_S + 0.2)  # whatever was cached before these evaluations has expired

    with league_server.client() as anonymous:  # public
        response = anonymous.get("/api/leaderboard", params={"size": 100})
    assert response.status_code == 200, response.text
    assert response.headers["cache-control"] == "public, max-age=2"
    board = response.json()
    rows = board["items"]
    assert board["total"] == len(rows)
    assert [row["rank"] for row in rows] == list(range(1, len(rows) + 1))
    assert [score(row) for row in rows] == sorted((score(row) for row in rows), reverse=True)

    assert better["evaluation"]["completed"] > worse["evaluation"]["completed"] == 0
    mine = [row for row in rows if row["owner"] == name]
    assert len(mine) == 1
    evaluation = better["evaluation"]
    assert {k: mine[0][k] for k in ("submission_id", "name", "public", "completed", "episodes", "mean_return",
                                     "mean_steps", "mean_speed")} == {
        "submission_id": better["id"], "name": "better", "public": False, "completed": evaluation["completed"],
        "episodes": evaluation["episodes_total"], "mean_return": evaluation["mean_return"],
        "mean_steps": evaluation["mean_steps"], "mean_speed": evaluation["mean_speed"]}
    students = [row["owner"] for row in rows if row["owner"] != "baselines"]
    assert len(students) == len(set(students))  # one row per student
    assert [(row["submission_id"], row["name"], row["public"]) for row in rows if row["owner"] == "baselines"] == \
        [(baseline["id"], "heuristic", True)]
    assert outsider["id"] not in [row["submission_id"] for row in rows]  # another course's student
    for row in rows:
        assert (row["rating"] is None) == (row["mu"] is None) == (row["sigma"] is None)


def test_the_leaderboard_is_paginated(app_league):
    for completed in (3, 2, 1):  # at least three rows, whatever else the board holds
        app_league.submission(app_league.student("paged")[0], completed=completed)
    with app_league.client() as anonymous:
        full = anonymous.get("/api/leaderboard", params={"size": 100}).json()
        first = anonymous.get("/api/leaderboard", params={"size": 1}).json()
        second = anonymous.get("/api/leaderboard", params={"size": 1, "page": 2}).json()
        assert anonymous.get("/api/leaderboard", params={"size": 101}).status_code == 422
        assert anonymous.get("/api/leaderboard", params={"page": 0}).status_code == 422
    assert first["total"] == second["total"] == full["total"] >= 3
    assert first["items"] == full["items"][:1]
    assert second["items"] == full["items"][1:2]


def parse_csv(response) -> list[dict]:
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/csv")
    return list(csv.DictReader(io.StringIO(response.text)))


def test_instructors_export_the_leaderboard_of_their_course_as_csv(app_league):
    """One line per student of the course, ranked as on the board; students without an evaluated
    agent last; an agent name a spreadsheet would run is defused."""
    course = unique("graded course")
    _, token = app_league.user("prof", role=INSTRUCTOR, course_name=course)
    (ann, _), (bob, _), (cy, _) = (app_league.user(name, course_name=course) for name in ("ann", "bob", "cy"))
    app_league.submission(ann, completed=1)
    best = app_league.submission(ann, completed=3)
    bob_agent = app_league.submission(bob, completed=2)
    with app_league.sessions.begin() as session:
        session.get(Submission, bob_agent.id).name = "=HYPERLINK(\"http://evil.example\")"
    with app_league.client(token) as instructor:
        rows = parse_csv(instructor.get("/api/leaderboard.csv"))
    with app_league.student("nosy")[1] as student:
        assert student.get("/api/leaderboard.csv").status_code == 403

    assert [(r["student"], r["submission_id"]) for r in rows] == [
        (ann.name, str(best.id)), (bob.name, str(bob_agent.id)), (cy.name, "")]
    assert rows[0]["rank"] == "1" and rows[1]["rank"] == "2" and rows[2]["rank"] == ""
    assert rows[1]["agent"] == "'=HYPERLINK(\"http://evil.example\")"
    assert (rows[0]["completed"], rows[0]["episodes"], float(rows[0]["mean_return"])) == ("3", "3", 6.0)
    assert rows[2]["completed"] == rows[2]["mean_return"] == rows[2]["rating"] == ""


@pytest.mark.slow
def test_an_agent_stays_on_the_leaderboard_while_it_is_evaluated_again(tmp_path, models):
    """Re-running evaluations (new settings) must not empty the board until a worker gets to them."""
    with fresh_backend("sqlite", tmp_path) as urls:
        server = make_server(tmp_path, urls)
        server.start_api()
        try:
            student = create_student(server, "mia")
            ready = upload_ready(student, models["onnx"])
            server.stop(server.api)
            server.start_api(embedded_worker=False)  # nobody will run the re-evaluation
            with server.client(server.instructor_token) as instructor:
                rerun = instructor.post("/api/evaluations/rerun", json={"submission_id": ready["id"]})
            assert rerun.status_code == 202, rerun.text
            assert student.get(f"/api/submissions/{ready['id']}").json()["evaluation"]["status"] == "queued"
            with server.client() as anonymous:
                rows = anonymous.get("/api/leaderboard", params={"size": 100}).json()["items"]
        finally:
            server.stop_all()
    mine = [row for row in rows if row["owner"] == "mia"]
    assert [(row["submission_id"], row["mean_return"]) for row in mine] == \
        [(ready["id"], ready["evaluation"]["mean_return"])]
