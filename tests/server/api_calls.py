"""What the tests do with a league over HTTP, whether it runs in this process
(tests/server/api/in_process.py) or as `league serve` and `league worker` processes
(tests/system/servers.py): upload, create a student, wait for a submission to settle, race; and
names that do not collide.
"""
from __future__ import annotations

import time
import uuid
from pathlib import Path

import httpx
import pytest

TERMINAL = {"ready", "rejected", "failed"}


def wait_for(fetch, done, timeout: float = 90, interval: float = 0.1):
    """Poll `fetch()` until `done(value)`; return the value (fail with the last one on timeout)."""
    deadline = time.monotonic() + timeout
    value = fetch()
    while not done(value):
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s; last value: {value}")
        time.sleep(interval)
        value = fetch()
    return value


def submission(client: httpx.Client, submission_id: int) -> dict:
    response = client.get(f"/api/submissions/{submission_id}")
    assert response.status_code == 200, response.text
    return response.json()


def episodes(client: httpx.Client, submission_id: int, evaluation_id: int, limit: int = 1000) -> list[dict]:
    """Every episode of an evaluation, page after page (the status answer carries none)."""
    items: list[dict] = []
    while True:
        response = client.get(f"/api/submissions/{submission_id}/episodes",
                              params={"evaluation_id": evaluation_id, "offset": len(items), "limit": limit})
        assert response.status_code == 200, response.text
        page = response.json()
        assert page["evaluation_id"] == evaluation_id
        items += page["items"]
        if len(items) >= page["total"] or not page["items"]:
            return items


def settled(value: dict) -> bool:
    """Validation finished, and if the submission is ready, its evaluation too."""
    if value["status"] not in TERMINAL:
        return False
    return value["status"] != "ready" or (value["evaluation"] or {}).get("status") in ("done", "failed")


def wait_settled(client: httpx.Client, submission_id: int, timeout: float = 90) -> dict:
    return wait_for(lambda: submission(client, submission_id), settled, timeout)


def upload(client: httpx.Client, path: Path, name: str | None = None) -> httpx.Response:
    with open(path, "rb") as handle:
        return client.post("/api/submissions", files={"file": (path.name, handle)},
                           data={"name": name or path.stem})


def create_student(league, name: str) -> httpx.Client:
    """A new student of `league` (in process, or a LeagueServer), as a client holding their token."""
    with league.client(league.instructor_token) as instructor:
        response = instructor.post("/api/users", json={"name": name})
    assert response.status_code == 201, response.text
    return league.client(response.json()["token"])


def post_race(client: httpx.Client, ids: list[int], **body) -> httpx.Response:
    return client.post("/api/races", json={"submission_ids": ids, **body})


def not_raceable(submission_id: int) -> dict:
    """The one answer for a submission that does not exist, is private, or is of another course."""
    return {"detail": f"no submission {submission_id} you may race: your own, the baselines, or another student's "
                      "agent once its owner makes it public"}


def unique(name: str) -> str:
    return f"{name}-{uuid.uuid4().hex[:6]}"
