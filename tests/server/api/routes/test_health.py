"""Health and the API's own documentation, in process."""
from __future__ import annotations

import re


def test_health_says_how_sandboxes_are_isolated(app_league):
    with app_league.client() as anonymous:
        health = anonymous.get("/api/health")
    assert health.status_code == 200
    body = health.json()
    assert body["status"] == "ok" and body["database"] in ("sqlite", "postgresql")
    sandbox = body["sandbox"]
    assert sandbox["required"] is True
    assert sandbox["full"] == (sandbox["problem"] is None and sandbox["landlock"] > 0 and sandbox["seccomp"])
    assert sandbox["full"], sandbox  # this machine has Landlock and seccomp: CI checks its sandboxes are isolated


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
