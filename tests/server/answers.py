"""Every answer a league gives about its state, collected over HTTP, and compared between two servers
(a backup's original and its restored copy; a database before and after an upgrade).

`collect` reads what users see: the leaderboard (every page) and its CSV, the accounts, every
submission with its episodes, every race with its replay and log, every championship with its rounds
and standings (and CSV), and each student's own view. `differences` compares two collections field by
field, over the fields both have (an upgrade may add fields), and lists what differs.
"""
from __future__ import annotations

from typing import Any, Callable

import httpx

PAGE = 100  # the API's largest page


def _pages(client: httpx.Client, path: str, **params: Any) -> list[Any]:
    items: list[Any] = []
    while True:
        page = _get(client, path, page=len(items) // PAGE + 1, size=PAGE, **params)
        items += page["items"]
        if len(items) >= page["total"] or not page["items"]:
            return items


def _get(client: httpx.Client, path: str, **params: Any) -> Any:
    response = client.get(path, params=params)
    assert response.status_code == 200, (path, response.status_code, response.text)
    kind = response.headers.get("content-type", "")
    return response.json() if kind.startswith("application/json") else response.text


def collect(url: str, instructor_token: str, student_tokens: list[str]) -> dict[str, Any]:
    """path -> answer (JSON, or the text of a CSV or a log) of every read about the league's state."""
    def client(token: str | None = None) -> httpx.Client:
        return httpx.Client(base_url=url, timeout=60, headers={"Authorization": f"Bearer {token}"} if token else {})

    answers: dict[str, Any] = {}
    with client() as public, client(instructor_token) as instructor:
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
