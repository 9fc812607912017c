"""Championships on a running league: which agent races for a student, instructors starting a
round at once, and a whole season -- two rounds in heats with students, the baseline and a broken
agent -- checked against the points table and raced again locally from what is stored. Who may run
them and what a bad one is refused with: tests/server/api/routes/."""
from __future__ import annotations

import csv
import io
import threading
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import numpy as np
import pytest

from league import testing as mf
from league.agents import export_onnx
from league.championship import split_into_heats
from league.evaluation import episode_seeds
from league.testing import thesis_driver

from ...server.api_calls import create_student, unique, upload, wait_for, wait_settled
from ...server.backends import fresh_backend
from ..servers import (
    add_user_in_new_course, assert_same_classification, baseline_submission, make_server, race_locally, stored_model,
    upload_ready, wait_race,
)

NAN_REASON = "the model returned NaN or infinite actions"


def create(client, **body):
    return client.post("/api/championships", json={"name": unique("cup"), **body})


# --------------------------------------------------------------------------- on the shared servers


def test_instructors_starting_a_round_at_once_start_one(league_server):
    baseline_submission(league_server)  # the baselines race in every course: a ready entrant
    token = add_user_in_new_course(league_server, unique("prof"), unique("course"), role="instructor")
    with league_server.client(token) as instructor:
        championship = create(instructor, heat_size=2).json()
    clicks = threading.Barrier(6)

    def start_round(_):
        with league_server.client(token) as instructor:
            clicks.wait()
            return instructor.post(f"/api/championships/{championship['id']}/rounds")

    with ThreadPoolExecutor(6) as pool:
        responses = list(pool.map(start_round, range(6)))
    assert sorted(r.status_code for r in responses) == [202] + [409] * 5, [r.text for r in responses]
    assert {r.json()["detail"] for r in responses if r.status_code == 409} <= {
        "another round of this championship was just started", "round 1 is still pending: wait for it to finish",
        "round 1 is still running: wait for it to finish"}
    with league_server.client(token) as instructor:
        rounds = wait_for(lambda: instructor.get(f"/api/championships/{championship['id']}").json()["rounds"],
                          lambda rounds: rounds[-1]["status"] in ("done", "failed"), timeout=120)
    assert [(r["number"], r["status"]) for r in rounds] == [(1, "done")]


def test_a_student_picks_the_submission_that_races_in_championships(league_server, models):
    student = create_student(league_server, unique("pat"))
    older = upload_ready(student, models["heuristic_onnx"], name="older")
    newer = upload_ready(student, models["onnx"], name="newer")
    rejected = wait_settled(student, upload(student, models["random_bytes"]).json()["id"])
    other = create_student(league_server, unique("ola"))

    def active_flags() -> dict[int, bool]:
        return {s["id"]: s["active"] for s in student.get("/api/submissions").json()}

    default = active_flags()  # the latest ready one, not the latest upload
    picked = student.patch(f"/api/submissions/{older['id']}", json={"active": True})
    after_pick = active_flags()
    detail = student.get(f"/api/submissions/{older['id']}").json()
    unready = student.patch(f"/api/submissions/{rejected['id']}", json={"active": True})
    not_theirs = other.patch(f"/api/submissions/{older['id']}", json={"active": True})
    unknown = student.patch("/api/submissions/999999", json={"active": True})
    after_refusals = active_flags()
    unpicked = student.patch(f"/api/submissions/{older['id']}", json={"active": False})
    after_unpick = active_flags()

    assert default == {older["id"]: False, newer["id"]: True, rejected["id"]: False}
    assert picked.status_code == 200, picked.text
    assert (picked.json()["id"], picked.json()["active"], picked.json()["public"]) == (older["id"], True, False)
    assert after_pick == {older["id"]: True, newer["id"]: False, rejected["id"]: False}
    assert detail["active"] is True
    assert unready.status_code == 409
    assert unready.json() == {"detail": f"submission {rejected['id']} is rejected: "
                                        "only a ready submission can race in championships"}
    assert not_theirs.status_code == unknown.status_code == 404
    assert not_theirs.json() == unknown.json() == {"detail": "no such submission of yours"}
    assert after_refusals == after_pick
    assert unpicked.status_code == 200 and unpicked.json()["active"] is False
    assert after_unpick == default


# --------------------------------------------------------------------------- a season


HEAT_SIZE = 3


POINTS = [10, 6, 4]


SEASON_SEED = 2024


SEASON_OPTIONS = {"n_obstacles": 4}


SPEEDS = {"ann": 0.2, "ben": 0.25, "cat": 0.3}


def heat_points(row: dict) -> int:
    """The points table by position; an agent that failed (dnf) scores nothing."""
    if row["outcome"] == "dnf" or row["position"] > len(POINTS):
        return 0
    return POINTS[row["position"] - 1]


def get_json(client, path: str, **params) -> dict:
    response = client.get(path, params=params)
    assert response.status_code == 200, response.text
    return response.json()


def wait_round(client, championship_id: int, number: int) -> dict:
    return wait_for(lambda: get_json(client, f"/api/championships/{championship_id}/rounds/{number}"),
                    lambda r: r["status"] in ("done", "failed"), timeout=180, interval=0.2)


@pytest.fixture(scope="module")
def season(tmp_path_factory, models):
    """A league of its own (fresh standings, no response cache, one friendly race a day), on SQLite
    only to keep the suite short (PostgreSQL has a scale-out test of its own): three students driving
    at different speeds, one whose agent passes validation but returns NaN in a race, one who picked
    an older agent, and the baseline. Two rounds of a championship in heats of 3."""
    tmp = tmp_path_factory.mktemp("season")
    drivers = tmp / "drivers"
    drivers.mkdir()
    with fresh_backend("sqlite", tmp) as database_url:
        server = make_server(tmp, database_url, LEAGUE_PUBLIC_CACHE_S="0", LEAGUE_RACE_QUOTA_PER_DAY="1")
        server.start_api()
        try:
            yield run_season(server, drivers, models)
        finally:
            server.stop_all()


def run_season(server, drivers, models) -> SimpleNamespace:
    s = SimpleNamespace(server=server, files={})
    instructor, member = server.client(server.instructor_token), server.client(server.instructor_token)  # member: names

    # before anyone has a ready agent
    empty = create(instructor, include_baselines=False).json()
    s.empty_round = instructor.post(f"/api/championships/{empty['id']}/rounds")

    s.students = {}
    for name, speed in SPEEDS.items():
        client = create_student(server, name)
        path = export_onnx(thesis_driver(target_speed=speed), drivers / f"{name}.onnx")
        s.students[name] = upload_ready(client, path, name=f"driver {speed}")
        s.files[s.students[name]["id"]] = path
        if name == "ann":  # a later upload that fails validation does not take her place
            ann = client
            assert wait_settled(client, upload(client, models["random_bytes"]).json()["id"])["status"] == "rejected"
    dnf = create_student(server, "dnf")
    broken = mf.onnx_nan_when_straight(drivers / "nan_when_straight.onnx")
    s.students["dnf"] = upload_ready(dnf, broken, name="nan when straight")
    s.files[s.students["dnf"]["id"]] = broken
    # dee races her older agent: she picked it after uploading a newer one
    dee = create_student(server, "dee")
    s.students["dee"] = upload_ready(dee, models["onnx"], name="dee picked")
    s.unpicked = upload_ready(dee, models["heuristic_onnx"], name="dee newer")
    assert dee.patch(f"/api/submissions/{s.students['dee']['id']}", json={"active": True}).status_code == 200
    s.files[s.students["dee"]["id"]] = models["onnx"]
    s.baseline = baseline_submission(server)
    s.files[s.baseline["id"]] = stored_model(server, s.baseline, drivers)

    # a friendly race, then the daily quota (LEAGUE_RACE_QUOTA_PER_DAY=1; championship heats do not count)
    s.friendly = ann.post("/api/races", json={"submission_ids": [s.students["ann"]["id"], s.baseline["id"]]})
    s.over_quota = ann.post("/api/races", json={"submission_ids": [s.students["ann"]["id"], s.baseline["id"]]})

    s.leaderboard_before = get_json(member, "/api/leaderboard")
    created = create(instructor, heat_size=HEAT_SIZE, points=POINTS, seed=SEASON_SEED, env_options=SEASON_OPTIONS)
    assert created.status_code == 201, created.text
    s.championship = created.json()
    cid = s.championship["id"]

    s.rounds, s.races, s.standings = [], [], []
    for number in (1, 2):
        response = instructor.post(f"/api/championships/{cid}/rounds")
        assert response.status_code == 202, response.text
        if number == 1:
            s.second_while_running = instructor.post(f"/api/championships/{cid}/rounds")
            s.running_standings = get_json(member, f"/api/championships/{cid}/standings")
        else:
            s.standings_during_round_2 = get_json(member, f"/api/championships/{cid}/standings")
            s.round_2_status_after = get_json(member, f"/api/championships/{cid}/rounds/2")["status"]
        s.rounds.append({"created": response.json(), "done": wait_round(member, cid, number)})
        s.races.append([wait_race(member, race_id) for race_id in s.rounds[-1]["done"]["race_ids"]])
        s.standings.append(get_json(member, f"/api/championships/{cid}/standings"))

    s.listed = get_json(member, "/api/races", championship_id=cid)
    s.championship_after = get_json(member, f"/api/championships/{cid}")
    s.standings_page = get_json(member, f"/api/championships/{cid}/standings", size=2, page=3)
    s.leaderboard_after = get_json(member, "/api/leaderboard")
    s.replay = get_json(member, f"/api/races/{s.races[0][0]['id']}/replay")
    s.dnf_heat = next(race for race in s.races[0]
                      if s.students["dnf"]["id"] in [e["submission_id"] for e in race["entrants"]])
    log_path = f"/api/races/{s.dnf_heat['id']}/log"
    s.heat_log, s.student_reads_log = instructor.get(log_path), ann.get(log_path)
    with server.client(add_user_in_new_course(server, "prof2", "another course", role="instructor")) as other:
        s.other_course_reads_log = other.get(log_path)
    instructor.close()
    member.close()
    return s


def entrant_ids(s) -> list[int]:
    return sorted([s.baseline["id"], *(sub["id"] for sub in s.students.values())])


def expected_standings(heats: list[dict]) -> dict[int, tuple[int, int, list[int]]]:
    """submission id -> (points, wins, finishes) summed by hand from the heats' classifications."""
    table: dict[int, tuple[int, int, list[int]]] = {}
    for race in heats:
        for row in race["classification"]:
            points, wins, finishes = table.get(row["submission_id"], (0, 0, []))
            table[row["submission_id"]] = (points + heat_points(row), wins + (row["position"] == 1),
                                           finishes + [row["position"]])
    return table


def test_friendly_races_count_against_the_daily_quota(season):
    assert season.friendly.status_code == 201, season.friendly.text
    assert season.over_quota.status_code == 429
    assert season.over_quota.json() == {
        "detail": "race quota reached: 1 friendly races per 24 hours; try again later"}
    with season.server.client(season.server.instructor_token) as member:  # races are the members' (the default)
        assert wait_race(member, season.friendly.json()["id"])["status"] == "done"
    assert season.friendly.json()["id"] not in [r["id"] for r in season.listed["items"]]


def test_a_round_needs_a_ready_submission(season):
    assert season.empty_round.status_code == 409
    assert season.empty_round.json() == {
        "detail": "no ready submission can race: students must upload an agent that passes validation"}


def test_a_round_waits_for_the_previous_one(season):
    refused = season.second_while_running
    assert refused.status_code == 409
    assert refused.json()["detail"] in ("round 1 is still pending: wait for it to finish",
                                        "round 1 is still running: wait for it to finish")
    assert season.running_standings == {"items": [], "total": 0}  # nothing counts before the round is over
    assert [r["number"] for r in season.championship_after["rounds"]] == [1, 2]


def test_a_round_with_students_baselines_and_a_broken_agent_completes(season):
    """The acceptance test of championships: the broken agent is a DNF with its reason, points and standings
    follow the points table, and every heat raced again from what is stored classifies the same."""
    broken_id = season.students["dnf"]["id"]
    assert season.students["dnf"]["evaluation"]["completed"] == 0  # it validated, then crashed on every track
    for number, (round_, races) in enumerate(zip(season.rounds, season.races), start=1):
        created, done = round_["created"], round_["done"]
        assert created["number"] == number and created["status"] in ("pending", "running")
        assert created["track_seed"] is None  # drawn secretly, shown once the round is over
        assert done["status"] == "done"
        assert done["heats_done"] == done["heats_total"] == 2 == len(done["heats"])
        assert isinstance(done["track_seed"], int)
        assert done["track_seed"] != episode_seeds(SEASON_SEED, number)[number - 1]
        assert sorted(i for heat in done["heats"] for i in heat) == entrant_ids(season)
        assert [len(heat) for heat in done["heats"]] == [3, 3]  # 6 entrants in heats of at most 3
        for k, (heat, race) in enumerate(zip(done["heats"], races), start=1):
            assert race["status"] == "done", race["error"]
            assert (race["championship_id"], race["round"], race["heat"]) == (season.championship["id"], number, k)
            assert (race["seed"], race["env_options"]) == (done["track_seed"], SEASON_OPTIONS)
            assert [e["submission_id"] for e in race["entrants"]] == heat
            assert [row["position"] for row in race["classification"]] == list(range(1, len(heat) + 1))
            for row in race["classification"]:
                if row["submission_id"] == broken_id:
                    assert (row["outcome"], row["reason"]) == ("dnf", NAN_REASON)
                else:
                    assert row["outcome"] != "dnf", row
    assert season.rounds[0]["done"]["track_seed"] != season.rounds[1]["done"]["track_seed"]

    # standings: the points table by position, summed; ordered by points, then wins
    for after_round, standings in enumerate(season.standings, start=1):
        expected = expected_standings([race for races in season.races[:after_round] for race in races])
        items = standings["items"]
        assert standings["total"] == len(items) == len(entrant_ids(season))
        assert [row["rank"] for row in items] == list(range(1, len(items) + 1))
        assert {row["submission_id"]: (row["points"], row["wins"], row["finishes"]) for row in items} == expected
        keys = [(-row["points"], -row["wins"]) for row in items]
        assert keys == sorted(keys)
        assert items[-1]["submission_id"] == broken_id and items[-1]["points"] == 0
        for row in items:
            assert row["rating"] == pytest.approx(row["mu"] - 3 * row["sigma"])
    assert season.standings_page["total"] == len(entrant_ids(season))
    assert season.standings_page["items"] == season.standings[1]["items"][4:]
    if season.round_2_status_after != "done":  # round 2's heats count once it is over
        assert season.standings_during_round_2 == season.standings[0]

    # the championship's races, as the races API lists them
    race_ids = [race_id for round_ in season.rounds for race_id in round_["done"]["race_ids"]]
    assert season.listed["total"] == 4
    assert sorted(r["id"] for r in season.listed["items"]) == sorted(race_ids)
    assert (season.replay["format"], season.replay["version"]) == ("microracer-replay", 1)
    assert len(season.replay["cars"]) == len(season.races[0][0]["entrants"])
    assert season.replay["seed"] == season.rounds[0]["done"]["track_seed"]  # the round's track, shown now


def test_every_heat_raced_again_locally_classifies_the_same(season):
    for races in season.races:
        for race in races:
            local = race_locally(race, season.files)
            assert_same_classification(race["classification"], local.classification)


def test_instructors_read_what_the_cars_sandboxes_printed(season):
    response = season.heat_log
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/plain")
    sections = response.text.split("== ")[1:]
    assert sorted(section.split(" ==\n")[0] for section in sections) == \
        sorted(f"{e['name']} ({e['owner']})" for e in season.dnf_heat["entrants"])
    assert all("started: Landlock ABI" in section for section in sections)
    assert season.student_reads_log.status_code == 403
    assert season.student_reads_log.json() == {"detail": "only instructors may do this"}
    assert season.other_course_reads_log.status_code == 403
    assert season.other_course_reads_log.json() == {"detail": "this race belongs to another course"}


def test_instructors_export_the_standings_as_csv(season):
    """The standings of the students (not the baseline) as the API gives them, then a student who
    never raced; read back with the csv module."""
    server, cid = season.server, season.championship["id"]
    late = create_student(server, unique("late"))
    with server.client(server.instructor_token) as instructor:
        response = instructor.get(f"/api/championships/{cid}/standings.csv")
        standings = get_json(instructor, f"/api/championships/{cid}/standings")["items"]
    with late:
        refused = late.get(f"/api/championships/{cid}/standings.csv")
        late_name = late.get("/api/users/me").json()["name"]
    assert refused.status_code == 403
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(response.text)))
    students = [row for row in standings if row["owner"] != "baselines"]
    assert len(students) == len(standings) - 1 == 5
    # ranked among students only (issue 23: the baseline took a rank and the first student had 2)
    assert [(r["rank"], r["student"], r["agent"], r["submission_id"], r["points"], r["wins"], r["heats"])
            for r in rows[:-1]] == [(str(rank), row["owner"], row["name"], str(row["submission_id"]),
                                     str(row["points"]), str(row["wins"]), str(len(row["finishes"])))
                                    for rank, row in enumerate(students, start=1)]
    assert [float(r["rating"]) for r in rows[:-1]] == pytest.approx([row["rating"] for row in students])
    assert rows[-1] == {**{key: "" for key in rows[-1]}, "student": late_name}


def test_heats_are_seeded_then_balanced_by_standing(season):
    ids = entrant_ids(season)
    first, second = season.rounds[0]["done"], season.rounds[1]["done"]
    assert first["heats"] == split_into_heats(ids, HEAT_SIZE, np.random.default_rng([SEASON_SEED, 1]))
    ranking = [row["submission_id"] for row in season.standings[0]["items"]]
    assert second["heats"] == split_into_heats(ids, HEAT_SIZE, np.random.default_rng([SEASON_SEED, 2]),
                                               ranking=ranking)
    # a snake draft: the leader and the runner-up race in different heats, and so do 3rd and 4th
    for a, b in ((ranking[0], ranking[1]), (ranking[2], ranking[3])):
        assert [a in heat for heat in second["heats"]] != [b in heat for heat in second["heats"]]


def test_the_leaderboard_shows_ratings_once_a_round_is_over(season):
    before, after = season.leaderboard_before, season.leaderboard_after
    assert before["total"] == after["total"] == len(entrant_ids(season))  # each student once, and the baseline
    assert [row["rating"] for row in before["items"]] == [None] * before["total"]
    ratings = {row["submission_id"]: row["rating"] for row in season.standings[1]["items"]}
    by_owner = {row["owner"]: row for row in after["items"]}
    assert set(by_owner) == {"ann", "ben", "cat", "dnf", "dee", "baselines"}
    for name, submission in [*season.students.items(), ("baselines", season.baseline)]:
        row = by_owner[name]
        if name == "dee":  # her best evaluated agent, not necessarily the one she races
            scores = {sub["id"]: (sub["evaluation"]["completed"], sub["evaluation"]["mean_return"])
                      for sub in (submission, season.unpicked)}
            assert scores[row["submission_id"]] == max(scores.values())
        else:
            assert row["submission_id"] == submission["id"]
        # issue 23: the rating was empty when the best agent was not the one raced: it is the raced one's
        raced = row["submission_id"] if row["submission_id"] in ratings else submission["id"]
        assert row["rating"] == pytest.approx(ratings[raced])
