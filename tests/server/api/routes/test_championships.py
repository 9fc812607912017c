"""Championships in process: who may run them and what a bad one is refused with. Which agent races
for a student, and a whole season raced by a worker: tests/system/api/test_championships.py."""
from __future__ import annotations


import pytest

from ...api_calls import create_student, unique

DEFAULT_POINTS = [25, 18, 15, 12, 10, 8, 6, 4, 2, 1]


def create(client, **body):
    return client.post("/api/championships", json={"name": unique("cup"), **body})


def test_only_instructors_create_championships_and_start_rounds(app_league):
    student = create_student(app_league, unique("sam"))
    with app_league.client(app_league.instructor_token) as instructor, app_league.client() as anonymous:
        by_student = create(student)
        by_nobody = create(anonymous)
        championship = create(instructor).json()
        round_by_student = student.post(f"/api/championships/{championship['id']}/rounds")
        round_by_nobody = anonymous.post(f"/api/championships/{championship['id']}/rounds")
        shown = student.get(f"/api/championships/{championship['id']}").json()  # members see it (the default)
        hidden = anonymous.get(f"/api/championships/{championship['id']}")
    assert hidden.status_code == 401
    assert by_student.status_code == round_by_student.status_code == 403
    assert by_student.json() == round_by_student.json() == {"detail": "only instructors may do this"}
    assert by_nobody.status_code == round_by_nobody.status_code == 401
    assert shown["rounds"] == []


def test_an_instructor_creates_a_championship_with_the_defaults(app_league):
    member = create_student(app_league, unique("member"))  # the boards are the members' (the default)
    with app_league.client(app_league.instructor_token) as instructor, member:
        response = instructor.post("/api/championships", json={"name": "  Spring cup  "})
        seeded = create(instructor, seed=77, heat_size=4, points=[3, 2, 1], include_baselines=False,
                        env_options={"obstacles": False})
        listing = member.get("/api/championships")
        shown = member.get(f"/api/championships/{response.json()['id']}")
        standings = member.get(f"/api/championships/{response.json()['id']}/standings")
        no_round = member.get(f"/api/championships/{response.json()['id']}/rounds/1")
    assert response.status_code == 201, response.text
    created = response.json()
    assert {k: created[k] for k in ("name", "env_options", "heat_size", "points", "include_baselines", "rounds")} == {
        "name": "Spring cup", "env_options": {}, "heat_size": 10, "points": DEFAULT_POINTS,
        "include_baselines": True, "rounds": []}
    assert isinstance(created["seed"], int) and 0 <= created["seed"] < 2**31  # drawn, and kept
    assert shown.status_code == 200 and shown.json() == created
    assert seeded.status_code == 201
    assert {k: seeded.json()[k] for k in ("seed", "heat_size", "points", "include_baselines", "env_options")} == {
        "seed": 77, "heat_size": 4, "points": [3, 2, 1], "include_baselines": False,
        "env_options": {"obstacles": False}}
    ids = [c["id"] for c in listing.json()]
    assert listing.status_code == 200 and created["id"] in ids and seeded.json()["id"] in ids
    assert ids == sorted(ids)
    assert standings.status_code == 200 and standings.json() == {"items": [], "total": 0}
    assert standings.headers["cache-control"].startswith("private")  # real names: a member's answer
    assert no_round.status_code == 404
    assert no_round.json() == {"detail": f"championship {created['id']} has no round 1"}


@pytest.mark.parametrize("body, detail", [
    ({"heat_size": 11}, "heat_size 11 is too large: a race takes at most 10 cars"),
    ({"points": [25, 18, -1]}, "points must not be negative"),
    ({"env_options": {"curves": 2}}, "invalid env_options: curves must be an integer in [5, 60], got 2"),
    ({"env_options": {"bogus": True}},
     "invalid env_options: RaceOptions() got an unexpected keyword argument 'bogus'; valid options: "),
    ({"env_options": {"observation": "lidar"}},
     "observation is not an evaluation setting: it follows each agent's input size"),
])
def test_a_bad_championship_is_refused(app_league, body, detail):
    with app_league.client(app_league.instructor_token) as instructor:
        before = len(instructor.get("/api/championships").json())
        response = create(instructor, **body)
        after = len(instructor.get("/api/championships").json())
    assert response.status_code == 422
    assert response.json()["detail"].startswith(detail)
    assert after == before


@pytest.mark.parametrize("body, detail", [
    ({"heat_size": 1}, "heat_size: Input should be greater than or equal to 2"),
    ({"points": []}, "points: List should have at least 1 item after validation, not 0"),
    ({"name": ""}, "name: String should have at least 1 character"),
    ({"seed": -1, "heat_size": "x"}, "heat_size: Input should be a valid integer, unable to parse string as an "
                                     "integer; seed: Input should be greater than or equal to 0"),
])
def test_a_championship_outside_the_schema_is_refused_in_one_sentence(app_league, body, detail):
    """Schema errors are {"detail": "text"} as every other error (docs/CONTRACT.md), naming each field."""
    with app_league.client(app_league.instructor_token) as instructor:
        response = create(instructor, **body)
    assert response.status_code == 422
    assert response.json() == {"detail": detail}


def test_unknown_championships_are_404(app_league):
    with app_league.client(app_league.instructor_token) as instructor:
        responses = [instructor.get("/api/championships/999999"), instructor.post("/api/championships/999999/rounds"),
                     instructor.get("/api/championships/999999/standings")]
    for response in responses:
        assert response.status_code == 404
        assert response.json() == {"detail": "championship 999999 does not exist"}


def test_an_instructor_of_another_course_cannot_start_a_round(app_league):
    with app_league.client(app_league.instructor_token) as instructor:
        championship = create(instructor).json()
    _, token = app_league.user("prof", role="instructor", course_name=unique("other course"))
    with app_league.client(token) as stranger:
        response = stranger.post(f"/api/championships/{championship['id']}/rounds")
    assert response.status_code == 403
    assert response.json() == {"detail": "this championship belongs to another course"}
