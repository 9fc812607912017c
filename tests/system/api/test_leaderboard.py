"""The course leaderboard on a running league (ratings before and after a round:
test_championships.py): each student's best agent and the baselines, and an agent that stays on the
board while a worker has yet to evaluate it again. Paging, the CSV and the cache: tests/server/api/routes/."""
from __future__ import annotations


from league import testing as mf

from ...server.api_calls import create_student, unique
from ...server.backends import fresh_backend
from ..servers import add_user_in_new_course, baseline_submission, make_server, upload_ready


def score(row: dict) -> tuple[float, float]:
    return (row["completed"] / row["episodes"], row["mean_return"])


def test_the_leaderboard_shows_each_students_best_agent_and_the_baselines(league_server, models, tmp_path):
    name = unique("lena")
    student = create_student(league_server, name)
    better = upload_ready(student, models["onnx"], name="better")
    worse = upload_ready(student, mf.onnx_nan_when_straight(tmp_path / "nan.onnx"), name="worse")  # the latest
    with league_server.client(add_user_in_new_course(league_server, unique("elsewhere"), unique("course"))) as other:
        outsider = upload_ready(other, models["heuristic_onnx"])
    baseline = baseline_submission(league_server)  # no waiting: the default cache shows finished evaluations at once

    with league_server.client() as anonymous:  # the members' board (the default): test_privacy.py, public ones
        assert anonymous.get("/api/leaderboard").status_code == 401
    response = student.get("/api/leaderboard", params={"size": 100})  # a member: real names, for them only
    assert response.status_code == 200, response.text
    assert response.headers["cache-control"] == "private, no-cache"
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


def test_an_agent_stays_on_the_leaderboard_while_it_is_evaluated_again(tmp_path, models):
    """Re-running evaluations (new settings) must not empty the board until a worker gets to them."""
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url)
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
            rows = student.get("/api/leaderboard", params={"size": 100}).json()["items"]  # a member: names
        finally:
            server.stop_all()
    mine = [row for row in rows if row["owner"] == "mia"]
    assert [(row["submission_id"], row["mean_return"]) for row in mine] == \
        [(ready["id"], ready["evaluation"]["mean_return"])]
