"""How the server serves the pages (league/server/pages.py), over real HTTP."""
from __future__ import annotations

import html
import json
import re

import httpx
import pytest

from league.server.geometry import track_geometry


@pytest.mark.parametrize("path,marker,current", [
    ("/", "pages/leaderboard.js", "/"), ("/login", "pages/login.js", None),
    ("/submissions", "pages/submissions.js", "/submissions"), ("/races/12", "pages/race.js", None),
    ("/replay", "pages/race.js", None), ("/instructor", "pages/instructor.js", "/instructor"),
    ("/integrity", "pages/integrity.js", "/instructor")])
def test_pages_are_html_that_may_load_from_their_own_server_only(web_server, path, marker, current):
    response = httpx.get(web_server.url + path)
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/html")
    assert marker in response.text
    # the shared header (league/web/layout.html) marks the page's own link, if it has one
    assert response.text.count('<nav class="site-nav"') == 1
    assert re.findall(r'<a href="([^"]+)" aria-current="page">', response.text) == ([current] if current else [])
    policy = response.headers["content-security-policy"]
    assert "default-src 'self'" in policy and "unsafe-inline" not in policy
    assert "http://" not in response.text.replace(web_server.url, "") and "https://" not in response.text


def test_pages_carry_the_toolkits_outcome_texts(web_server):
    from league.evaluation import OUTCOME_TEXT

    page = httpx.get(web_server.url + "/replay").text
    carried = re.search(r'<body [^>]*data-outcome-text="([^"]*)"', page).group(1)
    assert json.loads(html.unescape(carried)) == OUTCOME_TEXT


def test_assets_are_served_under_static(web_server):
    script = httpx.get(f"{web_server.url}/static/js/api.js")
    assert script.status_code == 200 and "javascript" in script.headers["content-type"]
    assert httpx.get(f"{web_server.url}/static/css/league.css").headers["content-type"].startswith("text/css")
    assert httpx.get(f"{web_server.url}/static/nothing.js").status_code == 404


def test_track_geometry_of_a_replays_track(web_server):
    from league.evaluation import race

    track = race(["heuristic"], seed=4).replay["track"]
    response = httpx.post(f"{web_server.url}/api/tracks/geometry", json=track)
    assert response.status_code == 200, response.text
    assert response.json() == track_geometry(track)


def test_track_geometry_refuses_what_is_not_a_track(web_server):
    response = httpx.post(f"{web_server.url}/api/tracks/geometry", json={"version": 1})
    assert response.status_code == 422
    assert response.json()["detail"].startswith("not a track: ")
    too_big = httpx.post(f"{web_server.url}/api/tracks/geometry", json={"padding": "x" * 300_000})
    assert too_big.status_code == 413
