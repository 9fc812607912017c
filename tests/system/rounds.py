"""Championship rounds on a `league serve` and its workers as the system tests drive them: the
students entered, a round started and waited for, and the check that each heat was raced once and
counted once in the standings (test_rounds.py, test_round_heats.py, test_hosts.py)."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

from ..server.api_calls import create_student, upload, wait_for, wait_settled
from .servers import LeagueServer

POINTS = [25, 18, 15, 12, 10, 8, 6, 4, 2, 1]
# standings read right after the round are fresh; one-episode evaluations: entering the agents is not the subject
ROUND_SETTINGS = {"LEAGUE_PUBLIC_CACHE_S": "0", "LEAGUE_EVAL_EPISODES": "1"}
ONE_AT_A_TIME = {"LEAGUE_WORKER_THREADS": "1"}
# heats of 2 cars in finer steps: a heat lasts long enough (> 0.5 s) for a worker to be killed in it
LONG_HEATS = {"tstep": 0.01, "max_episode_steps": 16000}


def enter_students(server: LeagueServer, files: list[Path]) -> list[int]:
    """One student per file, each with that agent uploaded and ready (validated and evaluated)."""
    ids = []
    for k, path in enumerate(files):
        student = create_student(server, f"student{k}")
        response = upload(student, path, name=f"driver{k}")
        assert response.status_code == 201, response.text
        ids.append(response.json()["id"])
        student.close()
    with server.client(server.instructor_token) as instructor:
        for submission_id in ids:
            settled = wait_settled(instructor, submission_id, timeout=120)
            assert settled["status"] == "ready", settled
            assert settled["evaluation"]["status"] == "done", settled["evaluation"]
    return ids


def wait_idle(server: LeagueServer, timeout: float = 120) -> None:
    """Until no job is queued or running (the baselines' evaluations included)."""
    with server.client(server.instructor_token) as instructor:
        wait_for(lambda: [j for j in instructor.get("/api/jobs").json() if j["status"] in ("queued", "running")],
                 lambda busy: not busy, timeout=timeout, interval=0.2)


def baseline_ids(server: LeagueServer) -> list[int]:
    with server.client(server.instructor_token) as instructor:
        listed = instructor.get("/api/submissions", params={"all": "true"}).json()
    return [s["id"] for s in listed if s["owner"] == "baselines" and s["status"] == "ready"]


def start_round(server: LeagueServer, **championship) -> tuple[int, dict]:
    with server.client(server.instructor_token) as instructor:
        created = instructor.post("/api/championships", json={"name": "Spring cup", "points": POINTS, "seed": 5,
                                                               **championship})
        assert created.status_code == 201, created.text
        championship_id = created.json()["id"]
        started = instructor.post(f"/api/championships/{championship_id}/rounds")
        assert started.status_code == 202, started.text
    return championship_id, started.json()


def read_round(server: LeagueServer, championship_id: int, number: int = 1) -> dict:
    with server.client(server.instructor_token) as member:  # the boards are the members' (the default)
        response = member.get(f"/api/championships/{championship_id}/rounds/{number}")
    assert response.status_code == 200, response.text
    return response.json()


def wait_round_over(server: LeagueServer, championship_id: int, timeout: float = 120) -> dict:
    return wait_for(lambda: read_round(server, championship_id), lambda r: r["status"] in ("done", "failed"),
                    timeout=timeout, interval=0.2)


def race_jobs(server: LeagueServer, race_ids: list[int]) -> list[dict]:
    with server.client(server.instructor_token) as instructor:
        jobs = instructor.get("/api/jobs", params={"limit": 1000}).json()
    return [j for j in jobs if j["kind"] == "race" and j["race_id"] in race_ids]


def races_of(server: LeagueServer, race_ids: list[int]) -> dict[int, dict]:
    with server.client(server.instructor_token) as member:  # the boards are the members' (the default)
        responses = {race_id: member.get(f"/api/races/{race_id}") for race_id in race_ids}
    assert all(r.status_code == 200 for r in responses.values()), [r.text for r in responses.values()]
    return {race_id: r.json() for race_id, r in responses.items()}


def standings(server: LeagueServer, championship_id: int) -> dict:
    with server.client(server.instructor_token) as member:  # the boards are the members' (the default)
        response = member.get(f"/api/championships/{championship_id}/standings", params={"size": 100})
    assert response.status_code == 200, response.text
    return response.json()


def heat_points(classification: list[dict]) -> dict[int, int]:
    """What the points table gives each car of one heat: by position, nothing for a DNF."""
    return {row["submission_id"]: POINTS[row["position"] - 1] if row["outcome"] != "dnf" else 0
            for row in classification}


def worker_pid(job: dict) -> int:
    """The pid part of a job's worker id ("hostname/pid/uuid8")."""
    return int(job["worker_id"].split("/")[-2])


def check_round_counted_once(server: LeagueServer, championship_id: int, finished: dict, entrants: list[int],
                             retried: tuple[int, ...] = ()) -> tuple[dict[int, dict], list[dict]]:
    """The finished round: each heat one race, each race done once (the `retried` races after one
    job that failed for good), each entrant in one heat and scored once in the standings. Returns
    the races and their jobs that did them."""
    race_ids = finished["race_ids"]
    assert finished["status"] == "done", finished
    assert finished["heats_done"] == finished["heats_total"] == len(finished["heats"]) == len(race_ids)
    assert len(set(race_ids)) == len(race_ids), f"a race appears twice: {race_ids}"
    assert sorted(i for heat in finished["heats"] for i in heat) == sorted(entrants)

    races = races_of(server, race_ids)
    with server.client(server.instructor_token) as member:  # the boards are the members' (the default)
        listed = member.get("/api/races", params={"championship_id": championship_id, "size": 100}).json()
    assert sorted(r["id"] for r in listed["items"]) == sorted(race_ids) and listed["total"] == len(race_ids)
    for heat_number, (race_id, heat) in enumerate(zip(race_ids, finished["heats"]), start=1):
        race = races[race_id]
        assert race["status"] == "done", race
        assert (race["championship_id"], race["round"], race["heat"]) == (championship_id, 1, heat_number)
        assert sorted(row["submission_id"] for row in race["classification"]) == sorted(heat)
        assert [row["position"] for row in race["classification"]] == list(range(1, len(heat) + 1))

    jobs = race_jobs(server, race_ids)
    assert sorted(j["race_id"] for j in jobs if j["status"] == "failed") == sorted(retried), jobs
    jobs = [j for j in jobs if j["status"] != "failed"]
    per_race = Counter(j["race_id"] for j in jobs)
    assert per_race == Counter(race_ids), f"not one job per race: {per_race}"
    assert all(j["status"] == "done" for j in jobs), jobs

    expected = Counter()
    for race in races.values():
        expected.update(heat_points(race["classification"]))
    table = standings(server, championship_id)
    assert table["total"] == len(entrants)
    assert {row["submission_id"]: row["points"] for row in table["items"]} == dict(expected)
    assert sum(row["points"] for row in table["items"]) == sum(expected.values())
    assert all(len(row["finishes"]) == 1 for row in table["items"]), table["items"]  # one heat each
    return races, jobs
