"""Health and the API's own documentation, in process."""
from __future__ import annotations

import os
import re

import pytest

from ..conftest import in_process_league


def test_health_says_how_sandboxes_are_isolated(app_league):
    with app_league.client() as anonymous:
        health = anonymous.get("/api/health")
    assert health.status_code == 200
    body = health.json()
    assert body["status"] == "ok" and body["database"] in ("sqlite", "postgresql")
    sandbox = body["sandbox"]
    assert sandbox["required"] is True
    assert sandbox["full"] == (sandbox["missing"] == [])
    assert sandbox["full"], sandbox  # this machine has Landlock and seccomp: CI checks its sandboxes are isolated
    assert sandbox["user"] == ("own user id" if os.geteuid() == 0 else "the server's user")
    assert sandbox["runtimes"] == ["onnx", "torchscript"]  # each loaded and ran in a probe sandbox


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
