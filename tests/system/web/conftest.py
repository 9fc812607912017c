"""Fixtures of the browser tests: a real `league serve` (SQLite, in-process worker) on a free port,
Debian's Chromium driven by Playwright, and a page that records every request it makes.

Needs `pip install playwright` (the wheel carries its driver; never `playwright install`) and
`apt-get install chromium`; the tests are skipped, saying so, when either is missing.
Screenshots go to test-artifacts/web/. The browser's helpers are in browsing.py.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import httpx
import pytest

from ..servers import running_server, wait_for_the_baselines
from .browsing import ARTIFACTS, CHROMIUM, CHROMIUM_ARGS, RecordedPage


@pytest.fixture(scope="package")
def web_server(tmp_path_factory):
    """A running `league serve` with the web pages, an instructor and the baselines bootstrapped."""
    with running_server(tmp_path_factory.mktemp("league-web"), "sqlite") as server:
        home = httpx.get(f"{server.url}/", timeout=10)
        if home.status_code != 200 or "text/html" not in home.headers.get("content-type", ""):
            pytest.fail("the web pages are not served: create_app must call "
                        "league.server.pages.mount_web(app, settings)")
        wait_for_the_baselines(server)
        yield server


@pytest.fixture(scope="package")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


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
