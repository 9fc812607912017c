"""Accessibility of the web pages (WCAG 2.1 A and AA) in a real browser against the real server:
axe-core on every page, the focus ring on every control, and the keyboard-only paths of the
common tasks, asserting where focus lands and what a screen reader is told.

The axe-core audit is axe.py's (the integrity page's tests use it too).
"""
from __future__ import annotations

import csv
import io
import json
from datetime import datetime, timedelta, timezone
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image  # matplotlib's
from playwright.sync_api import TimeoutError as PlaywrightTimeout
from playwright.sync_api import expect

from league.server.api.deps import UNKNOWN_TOKEN

from ...server.api_calls import unique, upload, wait_for, wait_settled
from ..servers import instructor_of_a_new_course, student_token
from .axe import DESKTOP, PHONE, Audit
from .browsing import require_browser, viewer_step
from .colours import contrast, hex_rgb

require_browser()

# What a screen reader is told: the text of a live region (role status or alert, or aria-live) each
# time it changes, if the region was rendered before the change (one that appears with its text,
# from display: none, is not read out by every screen reader).
ANNOUNCEMENTS = """
window.announcements = [];
(() => {
  const REGIONS = "[aria-live], [role=status], [role=alert]";
  const politeness = (region) => region.getAttribute("aria-live")
    || (region.getAttribute("role") === "alert" ? "assertive" : "polite");
  const rendered = new WeakMap();
  const scan = () => document.querySelectorAll(REGIONS)
    .forEach((region) => rendered.set(region, region.checkVisibility()));
  const observer = new MutationObserver((mutations) => {
    const changed = new Set(mutations.map((m) =>
      (m.target.nodeType === Node.ELEMENT_NODE ? m.target : m.target.parentElement)?.closest(REGIONS)));
    for (const region of changed) {
      const text = region?.textContent.replace(/\\s+/g, " ").trim();
      if (text && rendered.get(region) && politeness(region) !== "off") {
        window.announcements.push([politeness(region), text]);
      }
    }
    scan();
  });
  document.addEventListener("DOMContentLoaded", () => {
    scan();
    observer.observe(document.body, {subtree: true, childList: true, characterData: true});
  });
})();
"""


def announcements(web) -> list[tuple[str, str]]:
    return [tuple(item) for item in web.page.evaluate("window.announcements")]


def wait_announced(web, politeness: str, text: str) -> None:
    try:
        web.page.wait_for_function("([politeness, text]) => "
                                   "window.announcements.some(([p, t]) => p === politeness && t === text)",
                                   arg=[politeness, text], timeout=90_000)
    except Exception:
        pytest.fail(f"never announced ({politeness}): {text!r}; announced: {announcements(web)}")


def focused(web, selector: str) -> None:
    """Wait until the keyboard focus is on `selector` (fail saying where it is)."""
    try:
        web.page.wait_for_function("(selector) => document.activeElement.matches(selector)", arg=selector,
                                   timeout=30_000)
    except Exception:
        where = web.page.evaluate("document.activeElement.outerHTML.slice(0, 200)")
        pytest.fail(f"the focus is not on {selector} but on {where}")


def tab_to(web, selector: str, limit: int = 80) -> None:
    """Press Tab until the focus is on `selector`, as a keyboard user would."""
    for _ in range(limit):
        web.page.keyboard.press("Tab")
        if web.page.evaluate("(selector) => document.activeElement.matches(selector)", selector):
            return
    pytest.fail(f"{limit} presses of Tab never reached {selector}")


def open_file_chooser_by_keyboard(web, selector: str):
    """Space on the focused file input, as a keyboard user opens the chooser. On a loaded machine the
    first press may come while the page is still settling and be lost: the focus is checked (failing
    with where it is) and Space pressed again, three times at most."""
    for _ in range(3):
        focused(web, selector)
        try:
            with web.page.expect_file_chooser(timeout=10_000) as chooser:
                web.page.keyboard.press("Space")
            return chooser.value
        except PlaywrightTimeout:
            continue
    pytest.fail(f"Space on {selector} never opened the file chooser")


def keyboard_login(web, token: str) -> None:
    """Log in without a mouse: the login page has the focus in its token field."""
    web.goto("/login")
    focused(web, "#token")
    web.page.keyboard.type(token)
    web.page.keyboard.press("Enter")
    web.page.wait_for_url(lambda url: "/login" not in url)


@pytest.fixture(scope="module")
def course(web_server, agent_files, tmp_path_factory):
    """The shared course's instructor; a student with two ready submissions (the newer one active) and
    a rejected one; a revoked student; a championship whose first round (the course's active
    submissions and the baseline) is over.
    (The public pages show the shared course: a course of its own would not be on the leaderboard.)"""
    instructor = web_server.instructor_token
    student = student_token(web_server, unique("stu"))
    with web_server.client(student) as client:  # all three validated and evaluated at once
        uploads = [upload(client, agent_files[file], name).json()["id"] for file, name in
                   (("driver_0.25", "steady driver"), ("driver_0.3", "quick driver"), ("random_bytes", "random bytes"))]
        statuses = [wait_settled(client, submission_id)["status"] for submission_id in uploads]
        assert statuses == ["ready", "ready", "rejected"], statuses
    ready, _, rejected = uploads
    with web_server.client(instructor) as client:
        leaver = client.post("/api/users", json={"name": unique("leaver")}).json()
        assert client.post(f"/api/users/{leaver['id']}/revoke").status_code == 200
        championship = client.post("/api/championships",
                                   json={"name": unique("Cup"), "heat_size": 10, "seed": 5}).json()
        assert client.post(f"/api/championships/{championship['id']}/rounds").status_code == 202
        done = wait_for(lambda: client.get(f"/api/championships/{championship['id']}/rounds/1").json(),
                        lambda r: r["status"] in ("done", "failed"), timeout=120)
        assert done["status"] == "done", done
        replay = client.get(f"/api/races/{done['race_ids'][0]}/replay").json()
    with web_server.client(student) as member:  # a member's answers (the default visibility) are not kept
        assert member.get(f"/api/championships/{championship['id']}/standings").json()["items"]
    replay_path = tmp_path_factory.mktemp("a11y") / "heat.json"
    replay_path.write_text(json.dumps(replay))
    return SimpleNamespace(instructor=instructor, student=student, ready=ready, rejected=rejected,
                           championship=championship["id"], race=done["race_ids"][0], replay=replay_path)


# --------------------------------------------------------------------------- axe-core on every page


def test_axe_finds_nothing_on_the_leaderboard(web, course):
    audit = Audit(web)
    web.goto(f"/?championship={course.championship}")
    web.page.wait_for_selector("#board-closed:not([hidden])")  # the members' boards (the default)
    audit.check("logged out: asked to log in")
    web.login(course.student)
    web.goto(f"/?championship={course.championship}")
    web.page.wait_for_selector("#standings tbody tr[data-key]")
    audit.check("as a student")
    web.login(course.instructor)
    web.goto(f"/?championship={course.championship}")
    web.page.wait_for_selector("#standings-csv:not([hidden])")
    audit.check("as the instructor")
    audit.assert_clean()


def test_axe_finds_nothing_on_the_login_page(web):
    audit = Audit(web)
    web.goto("/login")
    audit.check("empty")
    web.page.fill("#token", "not-a-token")
    web.page.press("#token", "Enter")
    web.page.wait_for_selector("#login-message:not(:empty)")
    audit.check("a refused token")
    audit.assert_clean()


def test_axe_finds_nothing_on_the_submissions_page(web, course):
    audit = Audit(web)
    web.login(course.student)
    web.goto(f"/submissions?id={course.ready}")
    web.page.wait_for_selector("#chart-box:not([hidden])")
    web.page.click("#chart-box summary")
    audit.check("a ready submission")
    web.goto(f"/submissions?id={course.rejected}")
    web.page.wait_for_selector("#detail-error:not(:empty)")
    web.page.click("#validation-log-box summary")
    audit.check("a rejected submission")
    audit.assert_clean()


def test_axe_finds_nothing_in_the_race_viewers(web, course):
    audit = Audit(web)
    web.login(course.student)  # the races are the members' (the default)
    web.goto(f"/races/{course.race}?step=40")
    web.page.wait_for_selector("#viewer:not([hidden])")
    audit.check("a heat's replay")
    web.goto("/replay")
    audit.check("the replay file viewer, empty")
    web.page.set_input_files("#replay-file", str(course.replay))
    web.page.wait_for_selector("#viewer:not([hidden])")
    web.page.keyboard.press("End")
    audit.check("a replay file")
    audit.assert_clean()


def test_axe_finds_nothing_in_the_instructor_console(web, course):
    audit = Audit(web)
    web.login(course.instructor)
    web.page.wait_for_selector(f"[data-championship='{course.championship}'] [data-round='1']")
    web.page.wait_for_selector("#all-submissions tbody tr")
    audit.check("as it opens")
    web.page.fill("#student-name", unique("new"))
    web.page.click("#student-form button[type=submit]")
    web.page.wait_for_selector("#tokens:not([hidden])")
    web.page.click("#new-championship summary")
    audit.check("new tokens, the championship form open")
    web.page.click("#rerun-all")
    web.page.wait_for_selector("#rerun-dialog[open]")
    audit.check("asking to re-run every evaluation", widths=(DESKTOP,))
    web.page.keyboard.press("Escape")
    web.page.locator("#users button", has_text="Revoke").first.click()
    web.page.wait_for_selector("#revoke-dialog[open]")
    audit.check("asking to revoke an account", widths=(DESKTOP,))
    web.page.keyboard.press("Escape")
    web.page.locator("#assignments button", has_text="Publish").first.click()
    web.page.wait_for_selector("#publish-dialog[open]")
    audit.check("asking to publish an assignment", widths=(DESKTOP,))
    web.page.keyboard.press("Escape")  # the course's default assignment stays unpublished
    audit.assert_clean()


# --------------------------------------------------------------------------- the focus ring

# Where the focused control is drawn: its box, or its label's for a file input hidden in a drop zone.
FOCUSED_BOX = """() => {
  const focused = document.activeElement;
  if (!focused || focused === document.body) return null;
  let box = focused.getBoundingClientRect();
  if (box.width < 4 || box.height < 4 || getComputedStyle(focused).opacity === "0") {
    box = (focused.closest("label") || focused).getBoundingClientRect();
  }
  const name = focused.id || focused.dataset.focusKey || focused.getAttribute("aria-label")
    || focused.textContent.trim();
  return {left: box.left, top: box.top, right: box.right, bottom: box.bottom,
          name: `${focused.tagName} ${name.slice(0, 50)}`};
}"""
RING_DEPTH = 7  # CSS px outside the box where the ring is looked for (the site's: 5)
CORNER = 8  # CSS px at each end of a side where a rounded ring curves away


def screenshot(web, clip: dict) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(web.page.screenshot(clip=clip))).convert("RGB")).astype(float)


def sides_without_a_ring(focused: np.ndarray, unfocused: np.ndarray, box: tuple[int, int, int, int]) -> list[str]:
    """The sides of `box` along which focusing the control changed no pixel by 3:1 (WCAG 1.4.11)
    within RING_DEPTH px, on a tenth of their length or more (rounded corners left out); sides
    cut off by the screen's edge are not judged."""
    changed = contrast(focused, unfocused) >= 3
    left, top, right, bottom = box
    corner = min(CORNER, (bottom - top) // 3, (right - left) // 3)
    rows, columns = slice(top + corner, bottom - corner), slice(left + corner, right - corner)
    bands = {"top": (changed[max(top - RING_DEPTH, 0):top, columns], 0),
             "bottom": (changed[bottom:bottom + RING_DEPTH, columns], 0),
             "left": (changed[rows, max(left - RING_DEPTH, 0):left], 1),
             "right": (changed[rows, right:right + RING_DEPTH], 1)}
    return [side for side, (band, across) in bands.items() if band.shape[across] and band.any(axis=across).mean() < 0.9]


def focus_ring_problems(web, limit: int = 60) -> list[str]:
    """Tab through the page's controls from the first (the skip link); for each, compare the
    screen with and without its focus."""
    viewport = web.page.viewport_size
    problems, seen = [], set()
    web.page.focus(".skip-link")
    for step in range(limit):
        if step:
            web.page.keyboard.press("Tab")
        box = web.page.evaluate(FOCUSED_BOX)
        if box is None or box["name"] in seen:
            break
        seen.add(box["name"])
        clip = {"x": max(int(box["left"]) - RING_DEPTH, 0), "y": max(int(box["top"]) - RING_DEPTH, 0)}
        clip["width"] = min(int(np.ceil(box["right"])) + RING_DEPTH, viewport["width"]) - clip["x"]
        clip["height"] = min(int(np.ceil(box["bottom"])) + RING_DEPTH, viewport["height"]) - clip["y"]
        if clip["width"] <= 0 or clip["height"] <= 0:
            problems.append(f"{box['name']}: focused, but not on screen")
            continue
        focused_pixels = screenshot(web, clip)
        control = web.page.evaluate_handle("document.activeElement")
        web.page.evaluate("(control) => control.blur()", control)
        unfocused_pixels = screenshot(web, clip)
        web.page.evaluate("(control) => control.focus({preventScroll: true})", control)
        inside = (int(box["left"]) - clip["x"], int(box["top"]) - clip["y"],
                  int(np.ceil(box["right"])) - clip["x"], int(np.ceil(box["bottom"])) - clip["y"])
        missing = sides_without_a_ring(focused_pixels, unfocused_pixels, inside)
        if missing:
            problems.append(f"{box['name']}: no 3:1 focus ring on the {', '.join(missing)}")
    assert len(seen) > 5, f"Tab reached only {seen}"
    return problems


def test_every_control_shows_the_focus_ring(web, web_server, course):
    problems = {}
    web.login(course.student)  # the boards and races are the members' (the default)
    web.goto("/")
    web.page.wait_for_selector("#leaderboard tbody tr[data-key]")
    problems["leaderboard"] = focus_ring_problems(web)
    web.goto(f"/races/{course.race}?step=40")
    web.page.wait_for_selector("#viewer:not([hidden])")
    problems["race"] = focus_ring_problems(web)
    keyboard_login(web, course.student)
    web.page.wait_for_selector("#submissions tr[data-status]")
    problems["submissions"] = focus_ring_problems(web)
    instructor = instructor_of_a_new_course(web_server)  # few students: Tab reaches every part of the console
    with web_server.client(instructor) as client:
        assert client.post("/api/users", json={"name": unique("nia")}).status_code == 201
    keyboard_login(web, instructor)
    web.page.wait_for_selector("#users tbody button")
    problems["instructor"] = focus_ring_problems(web)
    assert not any(problems.values()), json.dumps(problems, indent=1, ensure_ascii=False)


# --------------------------------------------------------------------------- keyboard only


def test_login_by_keyboard(web, web_server):
    token = student_token(web_server, unique("kim"))
    web.page.add_init_script(ANNOUNCEMENTS)
    web.goto("/login")
    focused(web, "#token")
    web.page.keyboard.type("not-my-token")
    web.page.keyboard.press("Enter")
    wait_announced(web, "assertive", f"This token was not accepted: {UNKNOWN_TOKEN}.")
    focused(web, "#token")  # with the wrong token selected: typing replaces it
    web.page.keyboard.type(token)
    web.page.keyboard.press("Enter")
    web.page.wait_for_url(lambda url: url.endswith("/submissions"))
    web.page.keyboard.press("Tab")
    focused(web, ".skip-link")
    web.page.keyboard.press("Enter")
    focused(web, "main")
    web.page.keyboard.press("Tab")
    focused(web, "#model-file")  # the upload's drop zone: the page's first control


def test_upload_by_keyboard(web, web_server, agent_files):
    token = student_token(web_server, unique("lee"))
    web.page.add_init_script(ANNOUNCEMENTS)
    keyboard_login(web, token)
    web.page.wait_for_load_state("load")
    tab_to(web, "#model-file")
    web.screenshot("drop-zone-focused", full_page=False)
    open_file_chooser_by_keyboard(web, "#model-file").set_files(agent_files["driver_0.2"])
    expect(web.page.locator("#chosen-file")).to_contain_text("driver_0.2.onnx")
    web.page.keyboard.press("Tab")
    focused(web, "#submission-name")
    web.page.keyboard.type("keyboard driver")
    web.page.keyboard.press("Tab")
    focused(web, "#upload-button")
    web.page.keyboard.press("Enter")

    focused(web, "#detail-title")  # the new submission's details, which follow its status
    expect(web.page.locator("#detail-title")).to_contain_text("keyboard driver")
    wait_announced(web, "polite", "Uploaded driver_0.2.onnx: it is pending; it will be validated, then evaluated.")
    submission_id = int(web.page.get_attribute("#submissions tr[data-status]", "data-id"))
    evaluation = wait_settled(web_server.client(token), submission_id)["evaluation"]
    evaluated = (f"driver_0.2.onnx is evaluated: {evaluation['completed']} of {evaluation['episodes_total']} laps "
                 f"completed, mean return {evaluation['mean_return']:.2f}.")
    wait_announced(web, "polite", evaluated)
    said = [text for politeness, text in announcements(web) if text.startswith(("Upload", "driver_0.2"))]
    assert said[0].startswith("Uploading") and said[-1] == evaluated, said
    focused(web, "#detail-title")  # the page's polling kept it there
    web.screenshot("upload-by-keyboard", full_page=False)


def test_round_by_keyboard(web, web_server):
    web.page.add_init_script(ANNOUNCEMENTS)
    keyboard_login(web, web_server.instructor_token)  # the console lists the first course's championships
    tab_to(web, "#new-championship summary")
    web.page.keyboard.press("Enter")
    web.page.keyboard.press("Tab")
    focused(web, "#champ-name")
    name = unique("Keyboard Cup")
    web.page.keyboard.type(name)
    web.page.keyboard.press("Enter")

    wait_announced(web, "polite", f"Created the championship “{name}”.")
    card = web.page.locator("[data-championship]", has_text=name)
    championship_id = card.get_attribute("data-championship")
    focused(web, f"h3[data-focus-key='championship-{championship_id}']")
    web.page.keyboard.press("Tab")
    focused(web, f"[data-focus-key='run-{championship_id}']")
    web.page.keyboard.press("Enter")

    round_line = f"[data-championship='{championship_id}'] li[data-round='1']"
    focused(web, round_line)
    heats = web_server.client(web_server.instructor_token).get(
        f"/api/championships/{championship_id}/rounds/1").json()["heats_total"]
    heats_text = f"{heats} heat{'s' if heats > 1 else ''}"
    wait_announced(web, "polite", f"Round 1 of {name} started: {heats_text} to race.")
    wait_announced(web, "polite",
                   f"Round 1 of {name} is over: {heats} of {heats_text} done; the standings are updated.")
    said = [text for _, text in announcements(web) if text.startswith(f"Round 1 of {name}")]
    assert said == sorted(set(said), key=said.index), said  # each said once, in order
    expect(card.locator("[data-round='1'] .badge")).to_have_text("done")
    focused(web, round_line)  # the card was redrawn around it
    web.page.keyboard.press("Tab")
    focused(web, f"{round_line} a")  # Heat 1's replay


def test_revoke_by_keyboard_after_a_confirmation(web, web_server):
    instructor = instructor_of_a_new_course(web_server)
    name = unique("max")
    with web_server.client(instructor) as client:
        student = client.post("/api/users", json={"name": name}).json()
    web.page.add_init_script(ANNOUNCEMENTS)
    keyboard_login(web, instructor)
    revoke = f"[data-focus-key='revoke-{student['id']}']"
    tab_to(web, revoke)
    expect(web.page.locator(revoke)).to_have_accessible_name(f"Revoke {name}'s account")

    web.page.keyboard.press("Enter")  # asks first, Cancel focused: Enter again changes nothing
    focused(web, "#revoke-dialog[open] button[value=cancel]")
    expect(web.page.locator("#revoke-title")).to_have_text(f"Revoke {name}'s account?")
    web.screenshot("instructor-revoke-confirmation", full_page=False)
    web.page.keyboard.press("Escape")
    focused(web, revoke)
    assert web_server.client(student["token"]).get("/api/users/me").status_code == 200

    web.page.keyboard.press("Enter")
    focused(web, "#revoke-dialog[open] button[value=cancel]")
    web.page.keyboard.press("Shift+Tab")
    focused(web, "#revoke-dialog button[value=revoke]")
    web.page.keyboard.press("Enter")
    restore = f"[data-focus-key='token-{student['id']}']"
    focused(web, restore)  # the student's row, redrawn: "Restore with a new token"
    expect(web.page.locator(restore)).to_have_accessible_name(f"Restore with a new token for {name}")
    wait_announced(web, "polite", f"{name}'s token no longer works.")
    assert web_server.client(student["token"]).get("/api/users/me").status_code == 401


def test_publish_by_keyboard_after_a_confirmation_and_the_focus_on_the_outcome(web, web_server):
    instructor = instructor_of_a_new_course(web_server)
    past = (datetime.now(timezone.utc) - timedelta(hours=1)).isoformat()
    name = unique("Sprint")
    with web_server.client(instructor) as client:
        assignment = client.post("/api/assignments", json={"name": name, "episodes": 2, "due_at": past}).json()

    def published():
        return web_server.client(instructor).get(f"/api/assignments/{assignment['id']}").json()["published_at"]

    web.page.add_init_script(ANNOUNCEMENTS)
    keyboard_login(web, instructor)
    publish = f"[data-focus-key='publish-{assignment['id']}']"
    tab_to(web, publish, limit=200)
    expect(web.page.locator(publish)).to_have_accessible_name(f"Publish {name}")

    web.page.keyboard.press("Enter")  # asks first, Cancel focused: Enter again changes nothing
    focused(web, "#publish-dialog[open] button[value=cancel]")
    expect(web.page.locator("#publish-title")).to_have_text(f"Publish {name}?")
    expect(web.page.locator("#publish-summary")).to_contain_text("Publishing cannot be undone.")
    web.page.keyboard.press("Escape")
    focused(web, publish)
    assert published() is None

    web.page.keyboard.press("Enter")
    focused(web, "#publish-dialog[open] button[value=cancel]")
    web.page.keyboard.press("Shift+Tab")
    focused(web, "#publish-dialog button[value=publish]")
    web.page.keyboard.press("Enter")
    focused(web, f"[data-focus-key='published-{assignment['id']}']")  # the row's outcome, not the page's body
    wait_announced(web, "polite", f"Published {name}: the students see the private board.")
    assert published() is not None


def test_a_wide_table_scrolls_by_keyboard_on_a_phone(web, course):
    web.page.set_viewport_size(PHONE)
    web.login(course.student)  # the races are the members' (the default)
    web.goto(f"/races/{course.race}?step=40")
    web.page.wait_for_selector("#viewer:not([hidden])")
    region = web.page.locator(".table-wrap:has(#classification)")
    expect(region).to_have_attribute("role", "region")
    expect(region).to_have_accessible_name("Classification")
    tab_to(web, ".table-wrap:has(#classification)")
    for _ in range(5):
        web.page.keyboard.press("ArrowRight")
    web.page.wait_for_function("(region) => region.scrollLeft > 0", arg=region.element_handle())
    assert viewer_step(web) == 40  # the arrows scrolled the table, not the race
    web.page.set_viewport_size(DESKTOP)  # wide enough: a plain box again, no tab stop of its own
    expect(region).not_to_have_attribute("tabindex", "0")


# --------------------------------------------------------------------------- what the pages show


def test_new_tokens_stay_until_dismissed(web, web_server):
    web.login(instructor_of_a_new_course(web_server))
    names = [unique("ann"), unique("ben")]
    for name in names:
        web.page.fill("#student-name", name)
        web.page.click("#student-form button[type=submit]")
        expect(web.page.locator("#students-message")).to_have_text(f"Created {name}. Give them the token below.")
    rows = web.page.locator("#token-table tbody tr")
    expect(rows).to_have_count(2)
    assert [row.split("\t")[0] for row in rows.all_inner_texts()] == names[::-1]  # newest first
    first_token = rows.nth(1).locator(".token").inner_text()

    web.page.locator("#users button", has_text="New token").first.click()  # ann's: the list is oldest first
    expect(web.page.locator("#students-message")).to_have_text(
        f"New token for {names[0]} below (the old one no longer works).")
    expect(rows).to_have_count(2)  # ann's new token replaced her old one, at the top
    assert rows.nth(0).inner_text().startswith(names[0])
    assert rows.nth(0).locator(".token").inner_text() != first_token
    with web.page.expect_download() as download:
        web.page.click("#tokens-download")
    with open(download.value.path(), newline="") as saved:
        assert list(csv.reader(saved)) == [["name", "email", "student_id", "token"]] + [  # both creations
            [name, "", "", token] for name, token in (row.split("\t") for row in rows.all_inner_texts())]

    web.page.locator("#users button", has_text="Revoke").nth(1).click()  # ben's
    web.page.click("#revoke-dialog button[value=revoke]")
    expect(rows).to_have_count(1)  # a revoked token is no use
    web.screenshot("instructor-tokens", full_page=False)
    web.page.click("#tokens-dismiss")
    expect(web.page.locator("#tokens")).to_be_hidden()
    focused(web, "#student-name")


def test_the_instructor_reads_why_a_submission_was_rejected(web, web_server, course):
    error = web_server.client(course.student).get(f"/api/submissions/{course.rejected}").json()["error"]
    assert error
    web.login(course.instructor)
    reason = web.page.locator(f"#all-submissions tr[data-id='{course.rejected}'] .reason")
    expect(reason).to_have_text(error)
    expect(reason).to_be_visible()
    reason.scroll_into_view_if_needed()
    web.screenshot("instructor-rejection-reason", full_page=False)


def test_car_markers_carry_their_number_and_stand_out(web, course):
    web.login(course.student)  # the races are the members' (the default)
    web.goto(f"/races/{course.race}?step=40")
    web.page.wait_for_selector("#viewer:not([hidden])")
    drawn = web.page.evaluate("""async () => {
        const { carStyle } = await import("/static/js/palette.js");
        const painter = await import("/static/js/race-painter.js");
        const size = 4 * painter.MARKER_RADIUS;
        return [...Array(50).keys()].map((index) => {
          const canvas = document.createElement("canvas");
          canvas.width = canvas.height = size;
          const ctx = canvas.getContext("2d");
          ctx.fillStyle = painter.ROAD;
          ctx.fillRect(0, 0, size, size);
          painter.paintMarker(ctx, index, size / 2, size / 2, Math.PI / 2);
          return {...carStyle(index), pixels: [...ctx.getImageData(0, 0, size, size).data],
                  size, radius: painter.MARKER_RADIUS, road: painter.ROAD, offRoad: painter.OFF_ROAD,
                  edge: painter.MARKER_EDGE};
        });
    }""")
    first = drawn[0]
    for background in (first["road"], first["offRoad"]):  # the marker's outline (non-text contrast: 3:1)
        assert contrast(hex_rgb(first["edge"]), hex_rgb(background)) >= 3, background
    for index, marker in enumerate(drawn):
        assert marker["label"] == str(index + 1)
        assert contrast(hex_rgb(marker["labelColor"]), hex_rgb(marker["color"])) >= 4.5, marker  # text: 4.5:1
        pixels = np.array(marker["pixels"], dtype=float).reshape(marker["size"], marker["size"], 4)[..., :3]
        centre = pixels[marker["size"] // 2 - 4: marker["size"] // 2 + 4,
                        marker["size"] // 2 - 5: marker["size"] // 2 + 5]
        on_label = np.abs(centre - hex_rgb(marker["labelColor"])).sum(axis=-1) < 60
        on_fill = np.abs(centre - hex_rgb(marker["color"])).sum(axis=-1) < 60
        # the number, on the colour
        assert on_label.sum() >= 6 and on_fill.sum() >= 6, (index, on_label.sum(), on_fill.sum())
    legend = web.page.locator("#car-legend li svg text")
    assert legend.all_text_contents() == [str(i + 1) for i in range(legend.count())]
    web.page.locator(".race-stage").screenshot(
        path=str(web.screenshot("race-markers", full_page=False).parent / "race-markers-stage.png"))
