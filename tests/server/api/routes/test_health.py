"""Health and the API's own documentation, in process."""
from __future__ import annotations

import os
import re
from datetime import timedelta

import pytest
from sqlalchemy import update

import league as league_package
from league.server.db import crud
from league.server.db.models import Job, WorkerProcess, utcnow
from league.server.jobs import registry

from ...backends import BACKENDS
from ..in_process import in_process_league


def test_health_says_how_sandboxes_are_isolated(app_league):
    with app_league.client() as anonymous:
        body = anonymous.get("/api/health").json()  # (200 or 503: this league has no worker)
    assert body["database"] in ("sqlite", "postgresql")
    sandbox = body["sandbox"]
    assert sandbox["required"] is True
    assert sandbox["full"] == (sandbox["missing"] == [])
    assert sandbox["full"], sandbox  # this machine has Landlock and seccomp: CI checks its sandboxes are isolated
    assert sandbox["user"] == ("own user id" if os.geteuid() == 0 else "the server's user")
    assert sandbox["runtimes"] == ["onnx", "torchscript"]  # each loaded and ran in a probe sandbox


def ago(seconds: float):
    return utcnow() - timedelta(seconds=seconds)


@pytest.mark.parametrize("kind", BACKENDS)
def test_health_answers_503_while_jobs_wait_and_no_worker_is_alive(kind, tmp_path):
    """Queued jobs with no worker heard from in worker_silent_after_s (30 s) is an outage a load
    balancer or a monitor must see; a job younger than that is not yet (a worker may be starting)."""
    with in_process_league(kind, tmp_path, bootstrap=False) as league, league.client() as anonymous:
        def health() -> tuple[int, dict]:
            answer = anonymous.get("/api/health")
            return answer.status_code, answer.json()

        status, body = health()
        assert (status, body["status"], body["reason"], body["queued_jobs"], body["oldest_queued_s"],
                body["workers"]) == (200, "ok", None, 0, None, [])
        with league.sessions.begin() as session:
            job_ids = [crud.create_job(session, kind="validate", owner_id=None).id for _ in range(2)]
        status, body = health()
        assert (status, body["queued_jobs"], body["oldest_queued_s"] < 30) == (200, 2, True)

        with league.sessions.begin() as session:
            session.execute(update(Job).where(Job.id == job_ids[0]).values(enqueued_at=ago(95)))
        status, body = health()
        assert (status, body["status"], body["queued_jobs"]) == (503, "no_worker", 2)
        assert 95 <= body["oldest_queued_s"] < 125
        assert body["reason"] == (f"2 jobs queued, the oldest for {body['oldest_queued_s']:.0f} s, and no worker "
                                  f"heard from in the last 30 s: start `league worker` (or `league serve` without "
                                  f"--no-worker) on this database")

        worker_id = registry.register(league.sessions)
        status, body = health()
        assert (status, body["status"], body["reason"]) == (200, "ok", None)
        assert [(worker["pid"], worker["version"]) for worker in body["workers"]] == [(os.getpid(),
                                                                                       league_package.__version__)]

        with league.sessions.begin() as session:  # the worker died without a word
            session.execute(update(WorkerProcess).where(WorkerProcess.id == worker_id).values(heartbeat_at=ago(31)))
        assert health()[0] == 503


@pytest.mark.skipif(os.geteuid() != 0, reason="only a root server gives sandboxes user ids of their own")
def test_health_says_what_isolation_lacks_and_what_to_do(tmp_path):
    """A root server whose sandboxes keep root's user id (here: LEAGUE_SANDBOX_UID_BASE=0) is not
    fully isolated, and says why and what to do (as its start-up log does)."""
    with in_process_league("sqlite", tmp_path, sandbox_uid_base=0) as league, league.client() as anonymous:
        sandbox = anonymous.get("/api/health").json()["sandbox"]
    assert (sandbox["full"], sandbox["user"], sandbox["landlock"] > 0, sandbox["seccomp"]) == \
        (False, "root without capabilities", True, True)
    assert sandbox["missing"] == ["a user id of its own: LEAGUE_SANDBOX_UID_BASE is 0, so sandboxes run as root "
                                  "without capabilities, which still owns root's files and processes: unset it "
                                  "(each sandbox then runs as 1342177280 + its pid)"]


def test_the_api_docs_load_nothing_from_other_hosts(app_league):
    """Classrooms often have no internet: /docs and /redoc use files served by the league itself."""
    with app_league.client() as anonymous:
        for path in ("/docs", "/redoc"):
            page = anonymous.get(path)
            assert page.status_code == 200
            assets = re.findall(r'(?:src|href)="([^"]+)"', page.text) + re.findall(r"url: '([^']+)'", page.text)
            assert assets and not [url for url in assets if "://" in url or url.startswith("//")], assets
            for url in assets:
                assert anonymous.get(url).status_code == 200, url
