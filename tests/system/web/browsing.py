"""The browser of the web tests: Debian's Chromium driven by Playwright (skipped, saying so, when either
is missing), a page that records every request it makes, and where screenshots go.
"""
from __future__ import annotations

import base64
import os
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from ...server.commands import REPO

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


def viewer_step(web) -> int:
    """The step the race viewer shows."""
    return int(web.page.get_attribute("#viewer", "data-step"))


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
