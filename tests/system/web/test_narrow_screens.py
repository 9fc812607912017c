"""No page is wider than a 320 px screen (WCAG 1.4.10 reflow), for a visitor, a student and an
instructor, with a course's real controls on the pages: several assignments with long names (the
board's assignment picker and Tracks select, the console's lists), a ready submission, a race, the
console's board-visibility select. Wide tables scroll inside their own box (.table-wrap); what is
measured is the page's own width, `document.documentElement.scrollWidth`."""
from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from ...server.api_calls import unique
from ...server.api_calls import wait_settled
from ..servers import instructor_of_a_new_course, upload_ready, wait_race
from .axe import PHONE
from .browsing import require_browser

require_browser()

# names as long as courses write them: each is one option of a select, which is as wide as its longest
ASSIGNMENTS = ("Sprint one: a time trial on the public tracks", "Sprint two: overtaking in traffic (pairs)",
               "Final: the championship qualifier, private tracks")
WIDTH = """() => ({page: document.documentElement.scrollWidth,
  wider: [...document.querySelectorAll("body *")]
    .filter((node) => node.checkVisibility() && !node.closest(".table-wrap, dialog:not([open])")
                      && node.getBoundingClientRect().right > window.innerWidth + 0.5)
    .slice(0, 8).map((node) => `${node.tagName.toLowerCase()}${node.id ? "#" + node.id : ""} ` +
                               `(${Math.round(node.getBoundingClientRect().right)} px)`)})"""


def ready_baseline(server) -> int:
    """The bundled `heuristic` agent, once ready (its evaluation may take minutes on a loaded machine)."""
    with server.client(server.instructor_token) as instructor:
        listing = instructor.get("/api/submissions", params={"all": True}).json()
        baseline = next(s for s in listing if s["owner"] == "baselines" and s["name"] == "heuristic")
        return wait_settled(instructor, baseline["id"], timeout=600)["id"]


@pytest.fixture(scope="module")
def course(web_server, agent_files):
    """A course of its own: an instructor, a student with a ready submission and a race against a
    baseline, then three open assignments (the student's submission went to the only one open then)."""
    instructor = instructor_of_a_new_course(web_server)
    with web_server.client(instructor) as client:
        student = client.post("/api/users", json={"name": unique("Maximiliana Wolfeschlegelstein")}).json()
    with web_server.client(student["token"]) as client:  # a loaded machine: minutes, not seconds
        submission = upload_ready(client, agent_files["driver_0.25"], timeout=600)["id"]
        race = client.post("/api/races", json={"submission_ids": [submission, ready_baseline(web_server)]})
        assert race.status_code == 201, race.text
        race = race.json()
        assert wait_race(client, race["id"])["status"] == "done"
    with web_server.client(instructor) as client:
        for name in ASSIGNMENTS:
            created = client.post("/api/assignments", json={"name": name, "episodes": 2,
                                                            "due_at": "2099-01-01T00:00:00+00:00"})
            assert created.status_code == 201, created.text
        assert client.put("/api/settings/privacy", json={"board_visibility": "members"}).status_code == 200
    return SimpleNamespace(instructor=instructor, student=student["token"], race=race["id"])


def page_widths(web, role: str, paths: list[str], ready: dict[str, str]) -> dict[str, dict]:
    """Each page's width at 320 px once its own controls are drawn (`ready`: a selector to wait for)."""
    widths = {}
    for path in paths:
        web.goto(path)
        web.page.wait_for_load_state("networkidle")
        if path in ready:
            web.page.wait_for_selector(ready[path], state="attached")  # an option is never "visible"
        widths[path] = web.page.evaluate(WIDTH)
        web.screenshot(f"narrow-{role}-{path.strip('/').replace('/', '-') or 'leaderboard'}")
    return widths


def test_no_page_is_wider_than_a_320_px_screen_for_any_role(web, course):
    web.page.set_viewport_size(PHONE)
    race = f"/races/{course.race}"
    ready = {"/": "#leaderboard tbody tr", race: "#viewer:not([hidden])"}
    widths = {"visitor": page_widths(web, "visitor", ["/", "/login", "/replay"], {})}

    web.login(course.student)
    # the picker with every assignment (the course's default one too) and the Tracks select
    every_assignment = f"#assignment-picker:not([hidden]) #assignment option:nth-child({len(ASSIGNMENTS) + 1})"
    student_ready = {**ready, "/": every_assignment, "/submissions": "#submissions tr[data-status]"}
    widths["student"] = page_widths(web, "student", ["/", "/submissions", race, "/replay"], student_ready)

    web.page.evaluate("localStorage.clear()")
    web.login(course.instructor)
    instructor_ready = {**student_ready, "/submissions": "#submissions tbody tr", "/integrity": "#integrity-summary",
                        "/instructor": f"#assignments tbody tr:nth-child({len(ASSIGNMENTS) + 1}) button"}
    widths["instructor"] = page_widths(web, "instructor", ["/", "/instructor", "/submissions", "/integrity", race],
                                       instructor_ready)

    too_wide = {f"{role} {path}": width for role, pages in widths.items() for path, width in pages.items()
                if width["page"] > PHONE["width"]}
    assert not too_wide, json.dumps(too_wide, indent=1)
