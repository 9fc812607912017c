"""Friendly races on a running league (on SQLite and on PostgreSQL): a student races their agent
against the baseline over real HTTP, and the race is reproducible from what is stored; the race
settings with a worker stopped and started. The refusals: tests/server/api/routes/."""
from __future__ import annotations

import json
import threading
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import pytest

from league.evaluation import REPLAY_FORMAT, REPLAY_VERSION, load_replay

from ...server.api_calls import create_student, not_raceable, post_race, unique, upload, wait_settled
from ..servers import (
    add_user_in_new_course, assert_same_classification, baseline_submission, make_server, race_locally, stored_model,
    upload_ready, wait_race,
)

RACE_SEED = 4242
RACE_OPTIONS = {"n_obstacles": 4, "chicanes": False}
OUTCOMES = {"finished", "off_road", "wrong_direction", "too_slow", "timeout", "dnf"}


@pytest.fixture(scope="module")
def grid(league_server, models):
    """alice with a ready agent and a rejected upload, and the baseline."""
    alice_name = unique("alice")
    alice = create_student(league_server, alice_name)
    mine = upload_ready(alice, models["onnx"], name="alice actor")
    rejected = wait_settled(alice, upload(alice, models["random_bytes"]).json()["id"])
    assert rejected["status"] == "rejected"
    return SimpleNamespace(server=league_server, alice=alice, alice_name=alice_name, mine=mine, rejected=rejected,
                           baseline=baseline_submission(league_server), models=models)


@pytest.fixture(scope="module")
def finished_race(grid):
    created = grid.alice.post("/api/races", json={"submission_ids": [grid.mine["id"], grid.baseline["id"]],
                                                   "seed": RACE_SEED, "env_options": RACE_OPTIONS})
    assert created.status_code == 201, created.text
    return SimpleNamespace(created=created.json(), race=wait_race(grid.alice, created.json()["id"]))


def test_a_student_races_their_agent_against_the_baseline(grid, finished_race):
    created, race = finished_race.created, finished_race.race
    assert created == {"id": race["id"], "status": "pending"}
    assert race["status"] == "done", race["error"]
    assert race["error"] is None and race["finished_at"] is not None
    assert (race["seed"], race["env_options"]) == (RACE_SEED, RACE_OPTIONS)
    assert (race["championship_id"], race["round"], race["heat"]) == (None, None, None)
    entrants = [{"submission_id": grid.mine["id"], "name": "alice actor", "owner": grid.alice_name},
                {"submission_id": grid.baseline["id"], "name": "heuristic", "owner": "baselines"}]
    assert race["entrants"] == entrants

    rows = race["classification"]
    assert [row["position"] for row in rows] == [1, 2]
    assert sorted(row["car"] for row in rows) == ["car_0", "car_1"]
    for row in rows:
        car = int(row["car"].removeprefix("car_"))
        assert {k: row[k] for k in ("submission_id", "name", "owner")} == entrants[car]
        assert row["outcome"] in OUTCOMES
        assert row["time"] > 0 and row["distance"] > 0
        assert (row["reason"] is None) == (row["outcome"] == "finished")
    finishers = [row for row in rows if row["outcome"] == "finished"]
    assert rows[:len(finishers)] == finishers  # finishers first, by time
    assert [row["time"] for row in finishers] == sorted(row["time"] for row in finishers)


def test_the_replay_is_the_toolkits_replay_json(grid, finished_race, tmp_path):
    race = finished_race.race
    with grid.server.client(grid.server.instructor_token) as member:  # names (test_privacy.py: a visitor's)
        compressed = member.get(f"/api/races/{race['id']}/replay")  # httpx asks for gzip and unpacks it
        plain = member.get(f"/api/races/{race['id']}/replay", headers={"Accept-Encoding": "identity"})
    assert compressed.status_code == plain.status_code == 200
    assert compressed.headers["content-encoding"] == "gzip" and "content-encoding" not in plain.headers
    assert plain.headers["content-type"] == "application/json"
    replay = plain.json()
    assert compressed.json() == replay

    assert (replay["format"], replay["version"]) == (REPLAY_FORMAT, REPLAY_VERSION) == ("microracer-replay", 1)
    assert replay["seed"] == RACE_SEED
    assert replay["names"] == ["alice actor (" + grid.alice_name + ")", "heuristic (baselines)"]
    assert {k: replay["env_options"][k] for k in RACE_OPTIONS} == RACE_OPTIONS
    assert len(replay["cars"]) == 2
    for car, row in zip(replay["cars"], sorted(race["classification"], key=lambda r: r["car"])):
        steps = len(car["acc"])
        assert len(car["x"]) == len(car["y"]) == steps + 1 and len(car["turn"]) == steps
        assert steps * replay["tstep"] == pytest.approx(row["time"], abs=replay["tstep"])
    assert [r["position"] for r in replay["classification"]] == [r["position"] for r in race["classification"]]
    saved = tmp_path / "race.json"
    saved.write_bytes(plain.content)
    assert load_replay(saved) == replay  # what `league replay` reads


def test_a_race_is_reproducible_from_its_seed_options_and_models(grid, finished_race, tmp_path):
    race = finished_race.race
    files = {grid.mine["id"]: stored_model(grid.server, grid.mine, tmp_path),
             grid.baseline["id"]: stored_model(grid.server, grid.baseline, tmp_path)}

    local = race_locally(race, files)

    assert_same_classification(race["classification"], local.classification)
    served_replay = grid.alice.get(f"/api/races/{race['id']}/replay").json()
    local_replay = json.loads(json.dumps(local.replay))
    assert served_replay["track"] == local_replay["track"]
    assert served_replay["initial_speed"] == local_replay["initial_speed"]
    for served_car, local_car in zip(served_replay["cars"], local_replay["cars"]):
        assert len(served_car["x"]) == len(local_car["x"])
        assert served_car["x"] == pytest.approx(local_car["x"], abs=2e-5)
        assert served_car["y"] == pytest.approx(local_car["y"], abs=2e-5)


def test_races_are_listed_newest_first_and_paginated(grid, finished_race):
    race_id = finished_race.race["id"]
    with grid.server.client(grid.server.instructor_token) as member:  # names, as alice read the race
        listing = member.get("/api/races", params={"size": 100})
        first = member.get("/api/races", params={"size": 1})
        second = member.get("/api/races", params={"size": 1, "page": 2})
        none = member.get("/api/races", params={"championship_id": 10**9})
        bad_page = member.get("/api/races", params={"page": 0})
        shown = member.get(f"/api/races/{race_id}")
    assert listing.status_code == first.status_code == second.status_code == 200
    items, total = listing.json()["items"], listing.json()["total"]
    assert total == len(items) >= 1
    assert [r["id"] for r in items] == sorted((r["id"] for r in items), reverse=True)
    assert next(r for r in items if r["id"] == race_id) == finished_race.race == shown.json()
    assert first.json()["total"] == second.json()["total"] == total
    assert [r["id"] for r in first.json()["items"]] == [items[0]["id"]]
    if total > 1:
        assert [r["id"] for r in second.json()["items"]] == [items[1]["id"]]
    assert none.json() == {"items": [], "total": 0}
    assert bad_page.status_code == 422


def test_another_students_agent_races_only_once_public(grid, models):
    bob_name = unique("bob")
    bob = create_student(grid.server, bob_name)
    bobs = upload_ready(bob, models["heuristic_onnx"], name="bob driver")
    assert bobs["public"] is False

    refused = post_race(grid.alice, [grid.mine["id"], bobs["id"]])
    assert refused.status_code == 404  # as if it did not exist: a private agent's id tells nothing
    assert refused.json() == not_raceable(bobs["id"])
    assert grid.alice.patch(f"/api/submissions/{bobs['id']}", json={"public": True}).status_code == 404  # not hers

    made_public = bob.patch(f"/api/submissions/{bobs['id']}", json={"public": True})
    assert made_public.status_code == 200, made_public.text
    assert (made_public.json()["id"], made_public.json()["public"]) == (bobs["id"], True)
    assert [s["public"] for s in bob.get("/api/submissions").json()] == [True]

    allowed = post_race(grid.alice, [grid.mine["id"], bobs["id"]])
    assert allowed.status_code == 201, allowed.text
    without_hers = post_race(grid.alice, [grid.baseline["id"], bobs["id"]])
    assert without_hers.status_code == 403
    assert without_hers.json() == {"detail": "a friendly race needs one of your own submissions"}

    race = wait_race(grid.alice, allowed.json()["id"])
    assert race["status"] == "done", race["error"]
    assert {row["owner"] for row in race["classification"]} == {grid.alice_name, bob_name}


def test_an_agent_of_another_course_cannot_race(grid, models):
    token = add_user_in_new_course(grid.server, unique("outsider"), unique("other course"))
    with grid.server.client(token) as outsider:
        theirs = wait_settled(outsider, upload(outsider, models["heuristic_onnx"]).json()["id"])
        assert theirs["status"] == "ready"
        assert outsider.patch(f"/api/submissions/{theirs['id']}", json={"public": True}).status_code == 200

        from_here = post_race(grid.alice, [grid.mine["id"], theirs["id"]])
        from_there = post_race(outsider, [theirs["id"], grid.mine["id"]])
    with grid.server.client(grid.server.instructor_token) as instructor:
        by_instructor = post_race(instructor, [theirs["id"], grid.baseline["id"]])
    assert from_here.status_code == 404
    assert from_here.json() == not_raceable(theirs["id"])
    assert from_there.status_code == 404
    assert from_there.json() == not_raceable(grid.mine["id"])
    assert by_instructor.status_code == 404
    assert by_instructor.json() == not_raceable(theirs["id"])


@pytest.mark.parametrize("backend", ["postgres"], indirect=True)  # SQLite: the season in test_championships.py
def test_race_settings_limit_cars_and_daily_races_and_a_replay_waits_for_the_race(backend, tmp_path, models):
    """LEAGUE_MAX_RACE_CARS=2 and LEAGUE_RACE_QUOTA_PER_DAY=1; with no worker running, the race stays
    pending and its replay is a 409 until a worker races it."""
    _, database_url = backend
    server = make_server(tmp_path, database_url, LEAGUE_MAX_RACE_CARS="2", LEAGUE_RACE_QUOTA_PER_DAY="1")
    server.start_api(embedded_worker=False)
    worker = server.start_worker()
    try:
        student = create_student(server, "quinn")
        mine = upload_ready(student, models["onnx"])
        baseline = baseline_submission(server)
        server.stop(worker)  # from now on races wait in the queue

        too_many = post_race(student, [mine["id"], baseline["id"], 3])
        first = post_race(student, [mine["id"], baseline["id"]])
        pending = student.get(f"/api/races/{first.json()['id']}").json()
        early_replay = student.get(f"/api/races/{first.json()['id']}/replay")
        over_quota = post_race(student, [mine["id"], baseline["id"]], seed=1)
        with server.client(server.instructor_token) as instructor:
            by_instructor = post_race(instructor, [mine["id"], baseline["id"]])  # no quota for instructors

        server.start_worker()
        done = [wait_race(student, response.json()["id"]) for response in (first, by_instructor)]
        replay = student.get(f"/api/races/{first.json()['id']}/replay")
    finally:
        server.stop_all()
    assert too_many.status_code == 422
    assert too_many.json() == {"detail": "too many cars: 3; a race takes at most 2"}
    assert first.status_code == 201, first.text
    assert (pending["status"], pending["classification"], pending["finished_at"]) == ("pending", None, None)
    assert early_replay.status_code == 409
    assert early_replay.json() == {"detail": f"race {pending['id']} is pending: its replay exists once it is done"}
    assert over_quota.status_code == 429
    assert over_quota.json() == {"detail": "race quota reached: 1 friendly races per 24 hours; try again later"}
    assert by_instructor.status_code == 201, by_instructor.text
    assert [race["status"] for race in done] == ["done", "done"]
    assert replay.status_code == 200 and len(replay.json()["cars"]) == 2


def test_parallel_races_never_pass_the_daily_quota(grid):
    """40 friendly races posted at once against LEAGUE_RACE_QUOTA_PER_DAY (20): at most 20 accepted."""
    quota = 20
    name = unique("racer")
    racer = create_student(grid.server, name)
    token = racer.headers["Authorization"].split()[1]
    mine = upload_ready(racer, grid.models["heuristic_onnx"])
    start = threading.Barrier(40)

    def post(_):
        with grid.server.client(token) as client:
            start.wait()
            return post_race(client, [mine["id"], grid.baseline["id"]]).status_code

    with ThreadPoolExecutor(40) as pool:
        statuses = list(pool.map(post, range(40)))
    assert statuses.count(201) == quota and statuses.count(429) == 40 - quota, statuses
