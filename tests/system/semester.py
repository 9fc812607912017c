"""A league's state written and read over HTTP, to compare two servers (a backup's original and its
restored copy; a database before and after an upgrade).

`semester` writes a small one (students, evaluated submissions, a friendly race, a championship
round). `collect` reads what users see: the leaderboard (every page) and its CSV (rows by column),
the accounts, every submission with its episodes, every race with its replay and log, every
championship with its rounds and standings (and CSV), and each student's own view. `differences`
compares two collections field by field, over the fields both have (an upgrade may add fields),
and lists what differs.
"""
from __future__ import annotations

import csv
import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
from sqlalchemy import text

from league.server.db.session import make_engine

from ..server.api_calls import upload, wait_for, wait_settled
from .servers import LeagueServer, wait_race

PAGE = 100  # the API's largest page
STUDENTS = 3


def semester(server: LeagueServer, models: dict[str, Path]) -> list[str]:
    """Students with evaluated submissions, a friendly race and a championship round; their tokens."""
    with server.client(server.instructor_token) as instructor:
        tokens = [instructor.post("/api/users", json={"name": f"student{k}"}).json()["token"] for k in range(STUDENTS)]
        students = [server.client(token) for token in tokens]
        files = [models["onnx"], models["torchscript"], models["heuristic_onnx"]]
        sent = [upload(student, files[k], f"agent{k}").json()["id"] for k, student in enumerate(students)]
        mine = [wait_settled(student, submission_id) for student, submission_id in zip(students, sent)]
        assert [s["status"] for s in mine] == ["ready"] * STUDENTS
        students[1].patch(f"/api/submissions/{mine[1]['id']}", json={"public": True}).raise_for_status()
        race = students[0].post("/api/races", json={"submission_ids": [mine[0]["id"], mine[1]["id"]], "seed": 5})
        assert race.status_code == 201, race.text
        drained(server)  # the bundled baseline evaluated too: the round's entrants are the same in every run
        cup = instructor.post("/api/championships", json={"name": "cup", "heat_size": 2, "seed": 3}).json()
        instructor.post(f"/api/championships/{cup['id']}/rounds").raise_for_status()
        assert wait_race(students[0], race.json()["id"])["status"] == "done"
        wait_for(lambda: instructor.get(f"/api/championships/{cup['id']}/rounds/1").json()["status"],
                 lambda status: status in ("done", "failed"), timeout=120)
    for student in students:
        student.close()
    return tokens


def drained(server: LeagueServer, timeout: float = 120) -> None:
    """Every job of the league done or failed (jobs of the baselines' account included)."""
    engine = make_engine(server.env["LEAGUE_DATABASE_URL"])
    try:
        def waiting() -> int:
            with engine.connect() as connection:
                return connection.execute(text("SELECT count(*) FROM jobs WHERE status IN ('queued', 'running')")
                                          ).scalar_one()
        wait_for(waiting, lambda n: n == 0, timeout, interval=0.2)
    finally:
        engine.dispose()


def _pages(client: httpx.Client, path: str, **params: Any) -> list[Any]:
    items: list[Any] = []
    while True:
        page = _get(client, path, page=len(items) // PAGE + 1, size=PAGE, **params)
        items += page["items"]
        if len(items) >= page["total"] or not page["items"]:
            return items


def _get(client: httpx.Client, path: str, **params: Any) -> Any:
    """JSON, a CSV's rows as dicts (a newer version may add columns), or text."""
    response = client.get(path, params=params)
    assert response.status_code == 200, (path, response.status_code, response.text)
    kind = response.headers.get("content-type", "")
    if kind.startswith("text/csv"):
        return list(csv.DictReader(io.StringIO(response.text)))
    return response.json() if kind.startswith("application/json") else response.text


def collect(url: str, instructor_token: str, student_tokens: list[str]) -> dict[str, Any]:
    """path -> answer (JSON, or the text of a CSV or a log) of every read about the league's state."""
    def client(token: str | None = None) -> httpx.Client:
        return httpx.Client(base_url=url, timeout=60, headers={"Authorization": f"Bearer {token}"} if token else {})

    answers: dict[str, Any] = {}
    # the boards as the course's members see them (real names; a visitor of a public board sees display names)
    with client(instructor_token) as public, client(instructor_token) as instructor:
        answers["/api/leaderboard"] = _pages(public, "/api/leaderboard")
        for path in ("/api/leaderboard.csv", "/api/users", "/api/settings/evaluation"):
            answers[path] = _get(instructor, path)
        answers["/api/submissions?all=true"] = submissions = _get(instructor, "/api/submissions", all=True)
        for submission in submissions:
            path = f"/api/submissions/{submission['id']}"
            answers[path] = _get(instructor, path)
            if submission["evaluation"] and submission["evaluation"]["status"] == "done":
                answers[f"{path}/episodes"] = _get(instructor, f"{path}/episodes", limit=1000)
        answers["/api/races"] = races = _pages(public, "/api/races")
        for race in races:
            path = f"/api/races/{race['id']}"
            answers[path] = _get(public, path)
            if race["status"] == "done":
                answers[f"{path}/replay"] = _get(public, f"{path}/replay")
                answers[f"{path}/log"] = _get(instructor, f"{path}/log")
        answers["/api/championships"] = championships = _get(public, "/api/championships")
        for championship in championships:
            path = f"/api/championships/{championship['id']}"
            for number in range(1, len(championship["rounds"]) + 1):
                answers[f"{path}/rounds/{number}"] = _get(public, f"{path}/rounds/{number}")
            answers[f"{path}/standings"] = _pages(public, f"{path}/standings")
            answers[f"{path}/standings.csv"] = _get(instructor, f"{path}/standings.csv")
    for token in student_tokens:
        with client(token) as student:
            me = _get(student, "/api/users/me")
            answers[f"/api/users/me ({me['name']})"] = me
            answers[f"/api/submissions ({me['name']})"] = _get(student, "/api/submissions")
    return answers


def differences(ours: Any, theirs: Any, where: str = "", ignore: Callable[[str], bool] = lambda key: False,
                common_fields_only: bool = False) -> list[str]:
    """Where two answers differ ("path: ours != theirs"); dict keys for which `ignore(key)` is true are
    skipped, and with `common_fields_only` so are keys that only one side has."""
    if isinstance(ours, dict) and isinstance(theirs, dict):
        keys = set(ours) & set(theirs) if common_fields_only else set(ours) | set(theirs)
        found = []
        for key in sorted(keys, key=str):
            if ignore(str(key)):
                continue
            if key not in ours or key not in theirs:
                found.append(f"{where}.{key}: only on {'ours' if key in ours else 'theirs'}")
                continue
            found += differences(ours[key], theirs[key], f"{where}.{key}", ignore, common_fields_only)
        return found
    if isinstance(ours, list) and isinstance(theirs, list):
        if len(ours) != len(theirs):
            return [f"{where}: {len(ours)} items != {len(theirs)}"]
        return [d for i, (a, b) in enumerate(zip(ours, theirs))
                for d in differences(a, b, f"{where}[{i}]", ignore, common_fields_only)]
    return [] if ours == theirs else [f"{where}: {ours!r:.200} != {theirs!r:.200}"]
