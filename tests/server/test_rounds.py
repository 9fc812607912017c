"""A championship round's track (league/server/course/races.py) is drawn secretly when the round is created
and is shown once the round is over: before, nothing anyone can read derives it; while its heats are
raced, no answer (JSON, CSV, replay, log, page) holds its seed or its track; after, the stored seed
races it again.

In process, with the heats raced here as a worker races them (the toolkit's `race`, heuristic
drivers): the state between two heats is a state a test can stand in.
"""
from __future__ import annotations

import json

import pytest
from sqlalchemy import select

from league.evaluation import episode_seeds, race
from league.options import RaceOptions
from league.server.db.models import INSTRUCTOR, QUEUED, ChampionshipRound, Job, Race
from league.server.jobs.race import RaceOutcome, car_name, entrant_of, public
from league.track import episode_start

from .api.in_process import every_get, in_process_league
from .api_calls import unique
from .backends import BACKENDS

ALIKE = {"name": "cup", "seed": 5, "heat_size": 2, "include_baselines": False, "env_options": {"n_obstacles": 3}}


@pytest.fixture(scope="module", params=BACKENDS)
def app_league(request, tmp_path_factory):
    """The app in process on each backend (tests/server/api/in_process.py), no worker."""
    with in_process_league(request.param, tmp_path_factory.mktemp(f"rounds-{request.param}")) as league:
        yield league


def course_with_students(league, students: int) -> tuple[str, list[str]]:
    """A course of its own (its rounds race only these students): its instructor's token, and
    the tokens of `students` students who each have a ready submission."""
    course = unique("course")
    _, instructor = league.user("prof", role=INSTRUCTOR, course_name=course)
    with league.client(instructor) as client:  # visitors see its boards: their answers are walked too
        assert client.put("/api/settings/privacy", json={"board_visibility": "public"}).status_code == 200
    tokens = []
    for _ in range(students):
        user, token = league.user("racer", course_name=course)
        league.submission(user)
        tokens.append(token)
    return instructor, tokens


def stored_track_seed(league, championship_id: int, number: int = 1) -> int:
    with league.sessions() as session:
        return session.scalar(select(ChampionshipRound.track_seed).where(
            ChampionshipRound.championship_id == championship_id, ChampionshipRound.number == number))


def race_heat(league, race_id: int) -> None:
    """Race a heat as a worker does, with a heuristic driver in every car, from what is stored."""
    with league.sessions() as session:
        heat = session.get(Race, race_id)
        seed, options, entrants = heat.seed, heat.env_options, heat.entrants
        job_id = session.scalar(select(Job.id).where(Job.race_id == race_id, Job.status == QUEUED))
    result = race(["heuristic"] * len(entrants), seed=seed, names=[car_name(e) for e in entrants], **options)
    rows = [{**row, **entrant_of(entrants, row["car"])} for row in result.classification]
    league.finish_job(job_id, RaceOutcome(public(rows), result.replay, None, ""))


def secrets_of(seed: int, env_options: dict) -> list[str]:
    """What would give a round's track away, as text: its seed, and its control points' coordinates
    as JSON writes them (those of 12 characters or more: "0.0" would be found anywhere)."""
    track, _ = episode_start(seed, RaceOptions(**env_options))
    coordinates = [json.dumps(x) for point in track.to_dict()["control_points"] for x in point]
    return [str(seed), *(c for c in coordinates if len(c) >= 12)]


def walk(league, tokens: list[str | None], paths: list[str]) -> dict[tuple[str | None, str], object]:
    answers = {}
    for token in tokens:
        with league.client(token) as client:
            for path in paths:
                answers[token, path] = client.get(path)
    return answers


def assert_nothing_reveals(answers: dict, secrets: list[str]) -> None:
    for (_, path), response in answers.items():
        found = [secret for secret in secrets if secret in response.text]
        assert not found, f"GET {path} ({response.status_code}) reveals the round's track: {found}"


def test_a_rounds_track_is_drawn_when_the_round_is_created(app_league):
    """Two championships created alike answer alike, and still race different tracks: nothing in
    the championship derives its rounds' tracks (the heats, drawn from its seed, are the same)."""
    instructor_token, _ = course_with_students(app_league, 4)
    with app_league.client(instructor_token) as instructor, app_league.client() as anonymous:
        created = [instructor.post("/api/championships", json=ALIKE).json() for _ in range(2)]
        shown = [anonymous.get(f"/api/championships/{c['id']}").json() for c in created]
        rounds = [instructor.post(f"/api/championships/{c['id']}/rounds") for c in created]
    assert [r.status_code for r in rounds] == [202, 202], [r.text for r in rounds]

    def without_identity(championship: dict) -> dict:
        return {k: v for k, v in championship.items() if k not in ("id", "created_at")}

    assert without_identity(shown[0]) == without_identity(shown[1]) == without_identity(created[0])
    assert rounds[0].json()["heats"] == rounds[1].json()["heats"]
    assert rounds[0].json()["track_seed"] is rounds[1].json()["track_seed"] is None
    tracks = [stored_track_seed(app_league, c["id"]) for c in created]
    assert tracks[0] != tracks[1]
    assert episode_seeds(ALIKE["seed"], 1)[0] not in tracks  # the rule before: round n from the championship's seed


def test_a_rounds_track_is_secret_until_the_round_is_over(app_league):
    """Walk every GET route -- anonymous, as a student of the round, as its instructor -- while
    the round's heats are queued, then with one heat raced; no answer holds the round's seed or a
    control point of its track. Once the last heat is raced, its seed is shown, the replays draw its
    track, and the heats raced again from the served seed classify the same."""
    instructor_token, students = course_with_students(app_league, 4)
    with app_league.client(instructor_token) as instructor:
        championship = instructor.post("/api/championships", json={**ALIKE, "name": unique("cup")}).json()
        started = instructor.post(f"/api/championships/{championship['id']}/rounds")
    assert started.status_code == 202, started.text
    cid, heats = championship["id"], started.json()["race_ids"]
    assert len(heats) == 2
    seed = stored_track_seed(app_league, cid)
    secrets = secrets_of(seed, ALIKE["env_options"])
    assert len(secrets) > 10
    with app_league.client(students[0]) as student:
        mine = student.get("/api/submissions").json()[0]["id"]
        assignment = student.get("/api/assignments").json()[0]["id"]
    ids = {"championship_id": [cid], "number": [1], "race_id": heats, "submission_id": [mine],
           "filename": ["none.whl"], "assignment_id": [assignment]}
    paths = [*every_get(app_league.app, ids), f"/api/races?championship_id={cid}", "/api/jobs?limit=1000",
             f"/api/championships/{cid}/standings?size=100", "/api/submissions?all=true"]
    readers = [None, students[0], instructor_token]

    queued = walk(app_league, readers, paths)
    assert_nothing_reveals(queued, secrets)
    assert queued[None, f"/api/championships/{cid}/rounds/1"].json()["track_seed"] is None
    assert queued[None, f"/api/races/{heats[0]}"].json()["seed"] is None

    race_heat(app_league, heats[0])
    one_raced = walk(app_league, readers, paths)
    assert_nothing_reveals(one_raced, secrets)
    raced = one_raced[students[0], f"/api/races/{heats[0]}"].json()
    assert (raced["status"], raced["seed"]) == ("done", None) and raced["classification"]
    replay = one_raced[students[0], f"/api/races/{heats[0]}/replay"]
    assert replay.status_code == 409
    assert replay.json() == {"detail": f"race {heats[0]} is a heat of round 1, which is still being raced: "
                                       "its replay is shown once every heat of the round is over"}
    assert one_raced[None, f"/api/championships/{cid}/rounds/1"].json()["status"] == "running"

    race_heat(app_league, heats[1])
    with app_league.client(students[0]) as student:
        shown = student.get(f"/api/championships/{cid}/rounds/1").json()
        served = [student.get(f"/api/races/{race_id}").json() for race_id in heats]
        replays = [student.get(f"/api/races/{race_id}/replay").json() for race_id in heats]
        listed = student.get("/api/races", params={"championship_id": cid}).json()["items"]
    assert (shown["status"], shown["track_seed"]) == ("done", seed)
    assert [r["seed"] for r in served] == [r["seed"] for r in listed] == [seed, seed]
    track, _ = episode_start(seed, RaceOptions(**ALIKE["env_options"]))
    for heat, replay in zip(served, replays):
        assert replay["seed"] == seed and replay["track"] == json.loads(json.dumps(track.to_dict()))
        again = race(["heuristic"] * len(heat["entrants"]), seed=heat["seed"],
                     names=[car_name(e) for e in heat["entrants"]], **heat["env_options"])
        assert [(r["car"], r["position"], r["outcome"], r["time"]) for r in heat["classification"]] == \
            [(r["car"], r["position"], r["outcome"], r["time"]) for r in again.classification]
