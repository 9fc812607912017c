"""Fixtures of the browser tests: a real `league serve` (SQLite, in-process worker) on a free port,
Debian's Chromium driven by Playwright, and a page that records every request it makes.

Needs `pip install playwright` (the wheel carries its driver; never `playwright install`) and
`apt-get install chromium`; the tests are skipped, saying so, when either is missing.
Screenshots go to test-artifacts/web/.
"""
from __future__ import annotations

import base64
import os
import shutil
import uuid
from pathlib import Path
from urllib.parse import urlsplit

import httpx
import pytest

from ...server.conftest import REPO, fresh_backend, settled, wait_for
from ..servers import add_user_in_new_course, make_server

CHROMIUM = os.environ.get("LEAGUE_TEST_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]
ARTIFACTS = REPO / "test-artifacts" / "web"
TIMEOUT_MS = 30_000


def require_browser() -> None:
    """Skip, saying what to install, when Playwright or Chromium is missing (call at a test module's top)."""
    pytest.importorskip("playwright.sync_api", reason="browser tests need `pip install playwright`")
    if not Path(CHROMIUM).exists():
        pytest.skip(f"browser tests need Chromium at {CHROMIUM} (apt-get install chromium)", allow_module_level=True)


# --------------------------------------------------------------------------- helpers


def unique(name: str) -> str:
    return f"{name}-{uuid.uuid4().hex[:6]}"


def student_token(server, name: str) -> str:
    """A new student of the shared course (its instructor creates them); returns their token."""
    with server.client(server.instructor_token) as instructor:
        response = instructor.post("/api/users", json={"name": name})
    assert response.status_code == 201, response.text
    return response.json()["token"]


def instructor_of_a_new_course(server) -> str:
    """An instructor of a course of their own: their students, settings and re-runs change nothing
    another test sees (re-running the shared course's evaluations kept the worker busy for later tests)."""
    return add_user_in_new_course(server, unique("prof"), unique("course"), role="instructor")


def viewer_step(web) -> int:
    """The step the race viewer shows."""
    return int(web.page.get_attribute("#viewer", "data-step"))


# --------------------------------------------------------------------------- server and browser


@pytest.fixture(scope="package")
def web_server(tmp_path_factory):
    """A running `league serve` with the web pages, an instructor and the baselines bootstrapped."""
    tmp_path = tmp_path_factory.mktemp("league-web")
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url)
        server.start_api()
        try:
            home = httpx.get(f"{server.url}/", timeout=10)
            if home.status_code != 200 or "text/html" not in home.headers.get("content-type", ""):
                pytest.fail("the web pages are not served: create_app must call "
                            "league.server.pages.mount_web(app, settings)")
            wait_for_the_baselines(server)
            yield server
        finally:
            server.stop_all()


def wait_for_the_baselines(server) -> None:
    """Until the first start's baselines are evaluated, as users find the league after `league serve`:
    a test that came first would otherwise see (and the public cache keep) a league without them."""
    with server.client(server.instructor_token) as instructor:
        wait_for(lambda: instructor.get("/api/submissions?all=true").json(),
                 lambda submissions: submissions and all(settled(s) for s in submissions))


@pytest.fixture(scope="package")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


class RecordedPage:
    """A Playwright page plus every request it made and every uncaught script error."""

    def __init__(self, page, server_url: str):
        self.page = page
        self.base = server_url
        self.requests: list[str] = []
        self.errors: list[str] = []
        page.on("request", lambda request: self.requests.append(request.url))
        page.on("pageerror", lambda error: self.errors.append(str(error)))
        page.set_default_timeout(TIMEOUT_MS)

    def goto(self, path: str):
        return self.page.goto(self.base + path)

    def login(self, token: str) -> None:
        """Log in through the login page's form."""
        self.goto("/login")
        self.page.fill("#token", token)
        self.page.click("#login-form button[type=submit]")
        self.page.wait_for_url(lambda url: "/login" not in url)

    def screenshot(self, name: str, full_page: bool = True) -> Path:
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        path = ARTIFACTS / f"{name}.png"
        self.page.screenshot(path=str(path), full_page=full_page)
        return path

    def foreign_hosts(self) -> set[str]:
        own = urlsplit(self.base).netloc
        hosts = {urlsplit(url).netloc for url in self.requests
                 if urlsplit(url).scheme in ("http", "https", "ws", "wss")}
        return hosts - {own}

    def drop_file(self, selector: str, path: Path, name: str | None = None) -> None:
        """Drop a file on an element, as dragging it from the desktop does."""
        data = base64.b64encode(path.read_bytes()).decode()
        transfer = self.page.evaluate_handle(
            """([name, data]) => {
                 const bytes = Uint8Array.from(atob(data), (c) => c.charCodeAt(0));
                 const transfer = new DataTransfer();
                 transfer.items.add(new File([bytes], name));
                 return transfer;
               }""", [name or path.name, data])
        self.page.dispatch_event(selector, "dragover", {"dataTransfer": transfer})
        self.page.dispatch_event(selector, "drop", {"dataTransfer": transfer})


@pytest.fixture
def web(browser, web_server):
    """A fresh browser context (empty localStorage) on the test server; after the test, checks
    that the page asked nothing of any other host and threw no script error."""
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = RecordedPage(context.new_page(), web_server.url)
    try:
        yield page
    finally:
        context.close()
    assert page.requests, "the page made no request at all"
    assert not page.foreign_hosts(), f"requests to other hosts: {page.foreign_hosts()}"
    assert not page.errors, f"uncaught script errors: {page.errors}"


@pytest.fixture(scope="package")
def agent_files(tmp_path_factory) -> dict[str, Path]:
    """Agents to upload or race: thesis-size ONNX drivers at three speeds, and bad files."""
    pytest.importorskip("torch")
    from league.agents import export_onnx

    from league import testing as mf
    from league.testing import thesis_driver

    d = tmp_path_factory.mktemp("web-agents")
    files = {f"driver_{speed}": export_onnx(thesis_driver(target_speed=speed, seed=i), d / f"driver_{speed}.onnx")
             for i, speed in enumerate((0.2, 0.25, 0.3))}
    files["random_bytes"] = mf.random_bytes(d / "random.onnx")
    (d / "notes.txt").write_text("not a model")
    files["text"] = d / "notes.txt"
    (d / "empty.onnx").write_bytes(b"")
    files["empty"] = d / "empty.onnx"
    return files


@pytest.fixture(scope="package", autouse=True)
def clean_artifacts():
    shutil.rmtree(ARTIFACTS, ignore_errors=True)
    yield
