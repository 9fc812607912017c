"""The web pages (league/web/, package data): HTML for the leaderboard, login, submissions, race
viewer, instructor console and integrity report, and their assets under /static.

`mount_web(app, settings)` adds them to the FastAPI app. Each page is a Jinja2 template extending
league/web/layout.html (the head and header they share), filled with a few facts from the settings and
the toolkit (`page_facts`); the pages are otherwise plain HTML and JavaScript modules talking to the
JSON API (league.server.api.routes). They load nothing from any other host, which the
Content-Security-Policy sent with every page enforces in the browser.
"""
from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Any

from fastapi import APIRouter, FastAPI, Request
from fastapi.staticfiles import StaticFiles
from starlette.templating import Jinja2Templates

import league
from league import statuses
from league.championship import DEFAULT_POINTS
from league.constants import MODEL_SUFFIXES
from league.evaluation import OUTCOME_TEXT
from league.render import CAR_COLORS
from league.server.core.config import MB, Settings

# Pages may talk to and load from their own server only; no inline scripts or styles.
PAGE_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data: blob:; object-src 'none'; "
                               "base-uri 'none'; form-action 'self'; frame-ancestors 'none'",
    "Cache-Control": "no-cache",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}


def web_dir() -> Path:
    """The pages' folder, package data: found wherever the server runs from."""
    return Path(str(resources.files("league") / "web"))  # a directory: the package is installed unzipped


def page_facts(settings: Settings) -> dict[str, Any]:
    """What the templates show of the server and the toolkit: the upload limit and the model files it
    takes; the car colours (the race viewer's cars look as in `league race --save race.gif`); the outcome
    texts (a car's end is worded as the toolkit words it) and the status words (league.statuses: what the
    API answers), as JSON; the default points table of a championship; the version the footer names."""
    return {"version": league.__version__,
            "upload_limit": f"{settings.max_upload_bytes / MB:g} MB", "max_upload_bytes": settings.max_upload_bytes,
            "model_suffixes": ",".join(MODEL_SUFFIXES),
            "car_colors": " ".join("#{:02x}{:02x}{:02x}".format(*color) for color in CAR_COLORS),
            "outcome_text": json.dumps(OUTCOME_TEXT, separators=(",", ":")),
            "statuses": json.dumps(statuses.by_name(), separators=(",", ":")),
            "default_points": ", ".join(map(str, DEFAULT_POINTS))}


def mount_web(app: FastAPI, settings: Settings, directory: Path | None = None) -> None:
    """Serve the pages of `directory` (default `web_dir()`) on `app`."""
    directory = directory or web_dir()
    facts = page_facts(settings)
    templates = Jinja2Templates(directory=directory, context_processors=[lambda request: facts])

    def page(name: str):
        async def serve_page(request: Request):
            return templates.TemplateResponse(request, name, headers=PAGE_HEADERS)

        serve_page.__name__ = f"page_{Path(name).stem}"
        return serve_page

    pages = APIRouter(include_in_schema=False)
    pages.add_api_route("/", page("index.html"), methods=["GET", "HEAD"])
    pages.add_api_route("/login", page("login.html"), methods=["GET", "HEAD"])
    pages.add_api_route("/submissions", page("submissions.html"), methods=["GET", "HEAD"])
    pages.add_api_route("/races/{race_id}", page("race.html"), methods=["GET", "HEAD"])
    # the viewer for a replay file saved by `league race --save`
    pages.add_api_route("/replay", page("race.html"), methods=["GET", "HEAD"])
    pages.add_api_route("/instructor", page("instructor.html"), methods=["GET", "HEAD"])
    pages.add_api_route("/integrity", page("integrity.html"), methods=["GET", "HEAD"])
    app.include_router(pages)
    app.mount("/static", StaticFiles(directory=directory / "static"), name="static")
