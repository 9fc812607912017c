"""Health and the API's own documentation, in process."""
from __future__ import annotations

import importlib.metadata
import os
import re
from datetime import datetime, timedelta
from html.parser import HTMLParser

import pytest
from sqlalchemy import text, update

import league as league_package
from league.server.core.clock import utcnow
from league.server.db import crud
from league.server.db.models import Job, WorkerProcess
from league.server.db.session import head_revision
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
def test_health_is_degraded_while_no_worker_beats_whether_or_not_jobs_wait(kind, tmp_path):
    """No worker heard from in worker_silent_after_s (30 s) is an outage a load balancer or a monitor must
    see even with an empty queue (the next upload would wait for good); each registered worker is listed
    with its last heartbeat until its row expires (two silence windows)."""
    with in_process_league(kind, tmp_path, bootstrap=False) as league, league.client() as anonymous:
        def health() -> tuple[int, dict]:
            answer = anonymous.get("/api/health")
            return answer.status_code, answer.json()

        status, body = health()
        assert (status, body["status"], body["queued_jobs"], body["oldest_queued_s"], body["workers"]) == \
            (503, "degraded", 0, None, [])
        assert body["reason"] == ("no worker heard from in the last 30 s (no job queued, but the next upload would "
                                  "wait): start `league worker` (or `league serve` without --no-worker) on this "
                                  "database")

        worker_id = registry.register(league.sessions)
        status, body = health()
        assert (status, body["status"], body["reason"]) == (200, "ok", None)
        assert [(worker["pid"], worker["version"], worker["alive"]) for worker in body["workers"]] == \
            [(os.getpid(), league_package.__version__, True)]

        with league.sessions.begin() as session:
            job_ids = [crud.create_job(session, kind="validate", owner_id=None).id for _ in range(2)]
            session.execute(update(Job).where(Job.id == job_ids[0]).values(enqueued_at=ago(95)))
            session.execute(update(WorkerProcess).where(WorkerProcess.id == worker_id).values(heartbeat_at=ago(31)))
        status, body = health()  # the worker died without a word
        assert (status, body["status"], body["queued_jobs"]) == (503, "degraded", 2)
        assert 95 <= body["oldest_queued_s"] < 125
        assert body["reason"] == (f"no worker heard from in the last 30 s (2 jobs queued, the oldest for "
                                  f"{body['oldest_queued_s']:.0f} s): start `league worker` (or `league serve` "
                                  f"without --no-worker) on this database")
        [silent] = body["workers"]
        assert (silent["pid"], silent["alive"]) == (os.getpid(), False)
        assert 30 < (utcnow() - datetime.fromisoformat(silent["heartbeat_at"])
                     ).total_seconds() < 60

        with league.sessions.begin() as session:  # past two silence windows: its row expires at the next beat
            session.execute(update(WorkerProcess).where(WorkerProcess.id == worker_id).values(heartbeat_at=ago(61)))
        registry.beat(league.sessions, registry.register(league.sessions), league.settings.worker_silent_after_s)
        status, body = health()
        assert (status, [worker["alive"] for worker in body["workers"]]) == (200, [True])


def test_health_names_the_version_and_the_schema_it_needs(app_league):
    with app_league.client() as anonymous:
        body = anonymous.get("/api/health").json()
    assert (body["version"], body["schema_revision"]) == (importlib.metadata.version("microracer-league"),
                                                          head_revision())


@pytest.mark.parametrize("kind", BACKENDS)
def test_an_api_whose_schema_is_migrated_under_it_answers_503_saying_what_to_do(kind, tmp_path):
    """An upgrade that did not stop this API (an old process facing a newer schema): its next database
    error (a column renamed) is answered 503 with what to do instead of a 500, and so is every /api/
    request after it, /api/health saying "outdated"; back on its own schema it answers again."""
    with in_process_league(kind, tmp_path, worker_heartbeat_s=3600, worker_silent_after_s=7200) as league, \
            league.client(league.instructor_token) as instructor:  # (no beat sees it first: the error does)
        assert instructor.get("/api/leaderboard").status_code == 200
        with league.app.state.services.engine.begin() as connection:  # what a newer release's migration would do
            connection.execute(text("ALTER TABLE courses RENAME COLUMN name TO title"))
            connection.execute(text("UPDATE alembic_version SET version_num = '0099'"))
        expected = (f"the database's schema changed under this running process (microracer-league "
                    f"{league_package.__version__}): this database is at revision 0099, written by a newer version "
                    f"of microracer-league (this one, {league_package.__version__}, knows revisions up to "
                    f"{head_revision()}): upgrade this installation, then restart it")
        answer = instructor.get("/api/leaderboard")
        assert (answer.status_code, answer.json()) == (503, {"detail": expected})
        answer = instructor.get("/api/submissions")  # refused before it reaches the database
        assert (answer.status_code, answer.json(), answer.headers["retry-after"]) == (503, {"detail": expected}, "60")
        health = instructor.get("/api/health")
        assert (health.status_code, health.json()["status"], health.json()["reason"]) == (503, "outdated", expected)

        with league.app.state.services.engine.begin() as connection:  # rolled back
            connection.execute(text("ALTER TABLE courses RENAME COLUMN title TO name"))
            connection.execute(text(f"UPDATE alembic_version SET version_num = '{head_revision()}'"))
        assert league.app.state.watch.check() is None  # (what its next beat does)
        assert instructor.get("/api/leaderboard").status_code == 200


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


class VersionShown(HTMLParser):
    """The text of the element marked data-version (the footer's) in a page."""

    def __init__(self):
        super().__init__()
        self.inside, self.shown = False, []

    def handle_starttag(self, tag, attrs):
        self.inside = "data-version" in dict(attrs)

    def handle_endtag(self, tag):
        self.inside = False

    def handle_data(self, data):
        if self.inside:
            self.shown.append(data)


@pytest.mark.parametrize("page", ["/", "/login", "/submissions", "/instructor"])
def test_every_page_footer_names_the_version(app_league, page):
    with app_league.client() as anonymous:
        answer = anonymous.get(page)
    assert answer.status_code == 200
    parser = VersionShown()
    parser.feed(answer.text)
    assert parser.shown == [importlib.metadata.version("microracer-league")]
