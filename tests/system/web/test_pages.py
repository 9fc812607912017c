"""The web pages in a real browser (Chromium through Playwright) against a real `league serve`.

Every test runs in a fresh browser context; the `web` fixture then checks that the page asked
nothing of any host but the server and threw no script error. Screenshots: test-artifacts/web/.
"""
from __future__ import annotations

import csv
import io
import itertools
import json
import math
import re
from pathlib import Path

import pytest
from playwright.sync_api import expect

from league import render
from league.evaluation import OUTCOME_TEXT

from ...server.api_calls import unique, upload, wait_for, wait_settled
from ..servers import instructor_of_a_new_course, student_token
from .browsing import require_browser, viewer_step
from .colours import DEFICIENCIES, delta_e, hex_rgb

require_browser()

# The first cars' colours (the toolkit's, league/render.py) and a finished episode's (Okabe–Ito,
# league/web/static/js/palette.js).
CAR_COLORS = [tuple(color) for color in render.CAR_COLORS[:4]]
FINISHED_COLOR = (0x00, 0x9E, 0x73)
# CIEDE2000 above 10: two colours are clearly different at a glance.
CLEARLY_DIFFERENT = 10

CANVAS_PIXELS = """([selector, colors]) => {
  const canvas = document.querySelector(selector);
  const data = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
  const counts = colors.map(() => 0);
  const distinct = new Set();
  let hash = 0;
  for (let i = 0; i < data.length; i += 4) {
    const rgb = (data[i] << 16) | (data[i + 1] << 8) | data[i + 2];
    if (i % 28 === 0) distinct.add(rgb);
    hash = (Math.imul(hash, 31) + rgb) | 0;
    colors.forEach(([r, g, b], k) => { if (data[i] === r && data[i + 1] === g && data[i + 2] === b) counts[k]++; });
  }
  return {width: canvas.width, height: canvas.height, distinct: distinct.size, counts, hash};
}"""

# Records every status a submission row shows (the page updates rows in place while polling).
STATUS_RECORDER = """
window.seenStatuses = {};
new MutationObserver(() => {
  document.querySelectorAll("#submissions tr[data-status]").forEach((row) => {
    const seen = (window.seenStatuses[row.dataset.id] ||= []);
    if (seen[seen.length - 1] !== row.dataset.status) seen.push(row.dataset.status);
  });
}).observe(document, {subtree: true, childList: true, attributes: true});
"""


def canvas_pixels(web, selector: str, colors=()) -> dict:
    return web.page.evaluate(CANVAS_PIXELS, [selector, [list(c) for c in colors]])


def assert_drawn(pixels: dict, colors=()) -> None:
    """Not blank: a real picture (many colours), with every given colour present."""
    assert pixels["width"] > 100 and pixels["height"] > 100, pixels
    assert pixels["distinct"] > 8, f"the canvas looks blank: {pixels}"
    assert all(count > 0 for count in pixels["counts"]), f"missing colours {colors}: {pixels['counts']}"


def colors_on_track(server, race_url: str, step: int, apart: float = 0.05) -> list[tuple[int, int, int]]:
    """The colours of the first cars that the race's replay shows still racing at `step`, but for
    those a later-drawn car covers (two students may race the same file: the same trajectory)."""
    race_id = race_url.split("?")[0].rstrip("/").rsplit("/", 1)[1]
    cars = server.client(server.instructor_token).get(f"/api/races/{race_id}/replay").json()["cars"]
    where = {i: (car["x"][step], car["y"][step]) for i, car in enumerate(cars) if len(car["x"]) > step + 1}
    covered = {i for i in where for j in where if j > i and math.dist(where[i], where[j]) < apart}
    return [color for i, color in enumerate(CAR_COLORS) if i in where and i not in covered]


# --------------------------------------------------------------------------- login


def test_wrong_token_is_refused_with_the_servers_message(web):
    web.goto("/login")
    web.page.fill("#token", "not-a-real-token")
    web.page.click("#login-form button[type=submit]")

    message = web.page.locator("#login-message")
    message.wait_for()
    assert message.inner_text() == ("This token was not accepted: unknown token (replaced by a new one, or mistyped): "
                                    "ask your instructor for your current token.")
    assert web.page.url.endswith("/login")
    assert web.page.evaluate("localStorage.getItem('league.token')") is None


def test_revoked_token_sends_the_user_back_to_login_with_a_message(web, web_server):
    token = student_token(web_server, unique("leaver"))
    web.login(token)
    assert web.page.url.endswith("/submissions")
    # Off the league's pages while the token is revoked: every page of a course whose boards only its
    # members see polls with the token, and a poll answered 401 would log the user out before the
    # navigation below could show the message.
    web.page.goto("about:blank")
    with web_server.client(web_server.instructor_token) as instructor:
        me = web_server.client(token).get("/api/users/me").json()
        assert instructor.post(f"/api/users/{me['id']}/revoke").status_code == 200

    web.goto("/submissions")

    web.page.wait_for_url(re.compile(r"/login\?next=%2Fsubmissions$"))
    expect(web.page.locator("#login-message")).to_have_text(  # shown once the page's script has run
        "You were logged out: this account was revoked. Log in again with your token.")
    assert web.page.evaluate("localStorage.getItem('league.token')") is None
    web.screenshot("login-after-revoked-token")


@pytest.mark.parametrize("next_page, landing", [
    ("/leaderboard?page=2", "/leaderboard?page=2"),
    ("//evil.example/x", "/submissions"), ("/%5Cevil.example/x", "/submissions"),
    ("/%5C%5Cevil.example", "/submissions"), ("https://evil.example/", "/submissions"),
    ("javascript:alert(1)", "/submissions"), ("/.//evil.example/x", "/submissions"),
    ("/%2E//evil.example/x", "/submissions"), ("/%09/evil.example/x", "/submissions"),
    ("/\\evil.example/x", "/submissions"), ("/login?next=//evil.example", "/submissions"),
    ("/leaderboard?from=a//b", "/leaderboard?from=a//b")])
def test_login_goes_back_only_to_a_page_of_this_site(web, web_server, next_page, landing):
    web.goto(f"/login?next={next_page}")
    web.page.fill("#token", student_token(web_server, unique("back")))
    web.page.click("#login-form button[type=submit]")
    web.page.wait_for_url(lambda url: "/login" not in url)
    assert web.page.url == web.base + landing


def test_a_page_for_logged_in_users_asks_to_log_in_first(web):
    web.goto("/submissions")
    web.page.wait_for_url(re.compile(r"/login\?next=%2Fsubmissions$"))
    expect(web.page.locator("#login-message")).to_have_text("Log in with your token to see this page.")


# --------------------------------------------------------------------------- submissions


def test_student_uploads_an_agent_and_sees_it_ready_with_its_chart(web, web_server, agent_files):
    name = unique("alice")
    token = student_token(web_server, name)
    web.page.add_init_script(STATUS_RECORDER)
    web.login(token)
    assert web.page.url.endswith("/submissions")
    assert web.page.inner_text("[data-testid=account-name]") == f"{name} (student)"

    web.drop_file("#drop-zone", agent_files["driver_0.25"])
    assert "driver_0.25.onnx" in web.page.inner_text("#chosen-file")
    web.page.fill("#submission-name", "steady driver")
    web.page.click("#upload-button")

    row = web.page.locator("#submissions tr[data-status]").first
    web.page.wait_for_selector("#submissions tr[data-status=ready]", timeout=90_000)
    submission_id = int(row.get_attribute("data-id"))
    web.page.wait_for_selector("#chart-box:not([hidden])", timeout=90_000)

    seen = web.page.evaluate("window.seenStatuses")[str(submission_id)]
    # a worker may claim the job before the page's first look (workers wake on the upload's commit)
    assert seen[0] in ("pending", "validating") and seen[-1] == "ready", seen
    assert seen == [s for s in ("pending", "validating", "ready") if s in seen], seen  # in order, no reload

    api = wait_settled(web_server.client(token), submission_id)
    evaluation = api["evaluation"]
    expect(web.page.locator("#upload-message")).to_have_text(  # said once the page's poll sees it too
        f"driver_0.25.onnx is evaluated: {evaluation['completed']} of {evaluation['episodes_total']} laps completed, "
        f"mean return {evaluation['mean_return']:.2f}.")
    summary = web.page.inner_text("#evaluation-summary")
    assert summary.startswith(f"Completed {evaluation['completed']} of {evaluation['episodes_total']} laps")
    assert f"mean return {evaluation['mean_return']:.2f}" in summary
    versions = evaluation["versions"]  # what produced it, as `league evaluate` prints it
    assert web.page.inner_text("#evaluation-provenance") == (
        f"Simulator: physics {versions['physics']}, track format {versions['track_format']} "
        f"(league {versions['package']}) · result key {evaluation['result_key']}")
    assert_drawn(canvas_pixels(web, "#episode-chart", [FINISHED_COLOR]), [FINISHED_COLOR])
    assert web.page.get_attribute("#episode-chart", "aria-label").startswith(
        f"Chart of {evaluation['episodes_total']} episodes")
    legend = web.page.inner_text("#chart-legend")
    assert "finished" in legend and "mean speed" in legend
    assert web.page.locator("#episodes tbody tr").count() == evaluation["episodes_total"]
    web.screenshot("submissions-ready-with-chart")


def test_bad_uploads_show_the_servers_error(web, web_server, agent_files, tmp_path):
    token = student_token(web_server, unique("bob"))
    web.login(token)

    # the page states the uploads left today
    quota = int(web_server.env["LEAGUE_QUOTA_PER_DAY"])
    web.page.wait_for_selector("#upload-quota:not(:empty)")
    assert web.page.inner_text("#upload-quota") == \
        f"{quota} of {quota} uploads left in the last 24 hours (rejected uploads do not count)."

    # the page states the server's upload limit, and keeps a bigger file at home
    limit_mb = float(web_server.env["LEAGUE_MAX_UPLOAD_MB"])
    assert f"of at most {limit_mb:g} MB" in web.page.inner_text("#drop-zone")
    big = tmp_path / "big.onnx"
    big.write_bytes(bytes(int((limit_mb + 1) * 2**20)))
    posts = []
    web.page.on("request", lambda request: posts.append(request.url) if request.method == "POST" else None)
    web.page.set_input_files("#model-file", str(big))
    web.page.click("#upload-button")
    web.page.wait_for_selector("#upload-message.error")
    assert web.page.inner_text("#upload-message") == \
        f"big.onnx is {limit_mb + 1:.1f} MB, over the {limit_mb:g} MB limit: upload a smaller model file."
    assert posts == []

    # refused at once (4xx): the server's detail, word for word
    expected = upload(web_server.client(token), agent_files["text"]).json()["detail"]
    web.page.set_input_files("#model-file", str(agent_files["text"]))
    web.page.click("#upload-button")
    web.page.wait_for_selector("#upload-message.error")
    assert web.page.inner_text("#upload-message") == f"Upload refused: {expected}"

    web.page.set_input_files("#model-file", str(agent_files["empty"]))
    web.page.click("#upload-button")
    web.page.wait_for_function(
        "() => document.querySelector('#upload-message').textContent.startsWith('Upload refused: the')")
    assert web.page.inner_text("#upload-message") == "Upload refused: the file is empty"

    # accepted, then rejected by the sandbox: the stored error, on the upload and in the details
    web.page.set_input_files("#model-file", str(agent_files["random_bytes"]))
    web.page.click("#upload-button")
    web.page.wait_for_selector("#submissions tr[data-status=rejected]", timeout=90_000)
    submission_id = int(web.page.get_attribute("#submissions tr[data-status=rejected]", "data-id"))
    error = wait_settled(web_server.client(token), submission_id)["error"]
    assert error
    web.page.wait_for_selector("#upload-message.error")
    assert web.page.inner_text("#upload-message") == f"random.onnx was rejected: {error}"
    assert web.page.inner_text("#detail-error") == f"Rejected: {error}"
    assert web.page.inner_text("#upload-quota").startswith(f"{quota} of {quota} uploads left")  # rejected: free
    web.screenshot("submissions-rejected")


# --------------------------------------------------------------------------- race viewer (replay file)


@pytest.fixture(scope="module")
def replay_file(agent_files, tmp_path_factory):
    """A real 4-car race: the heuristic driver reading lidar, and three compact ONNX drivers at
    different speeds (the race's observation is then lidar, the drivers get their compact view)."""
    from league.evaluation import race, save_replay

    agents = ["heuristic-lidar", agent_files["driver_0.2"], agent_files["driver_0.25"], agent_files["driver_0.3"]]
    result = race(agents, seed=1, names=["heuristic", "slow", "steady", "quick"])
    return save_replay(result, tmp_path_factory.mktemp("replays") / "race.json"), result


def test_replay_viewer_draws_and_plays_a_race(web, replay_file):
    path, result = replay_file
    web.goto("/replay")
    web.page.set_input_files("#replay-file", str(path))
    web.page.wait_for_selector("#viewer:not([hidden])")
    total = max(len(car["x"]) for car in result.replay["cars"]) - 1

    # it plays at once: the step advances and the picture changes
    first = canvas_pixels(web, "#race-canvas")
    web.page.wait_for_function("() => Number(document.querySelector('#viewer').dataset.step) > 40")
    assert web.page.inner_text("#play-button") == "Pause"
    web.page.keyboard.press("Space")
    assert web.page.inner_text("#play-button") == "Play"
    paused_at = viewer_step(web)
    later = canvas_pixels(web, "#race-canvas", CAR_COLORS)
    assert_drawn(later, CAR_COLORS)  # track plus every car's colour
    assert later["hash"] != first["hash"]
    web.page.wait_for_timeout(300)
    assert viewer_step(web) == paused_at  # paused means paused
    legend = web.page.locator("#car-legend .car-status")
    assert re.fullmatch(r"(accelerating|braking) \d\.\d\d \| (left \d\.\d\d|right \d\.\d\d|straight) \| speed \d\.\d\d",
                        legend.nth(0).text_content())
    web.screenshot("replay-playing")

    # keyboard: one step, one second, start, finish
    web.page.keyboard.press("ArrowRight")
    assert viewer_step(web) == paused_at + 1
    web.page.keyboard.press("Shift+ArrowLeft")
    assert viewer_step(web) == paused_at + 1 - 25
    web.page.keyboard.press("Home")
    assert viewer_step(web) == 0
    web.page.keyboard.press("End")
    assert viewer_step(web) == total
    finals = [legend.nth(i).text_content() for i in range(4)]
    for row in result.classification:
        car = int(row["car"][4:])
        expected = f"{row['position']}{ {1: 'st', 2: 'nd', 3: 'rd'}.get(row['position'], 'th')}  {row['time']:.1f} s" \
            if row["outcome"] == "finished" else row["reason"]
        assert finals[car] == expected
    assert web.page.locator("#classification tbody tr").count() == 4
    # the race's lidar observation is not every car's
    assert "lidar observations (compact agents get their 5-number view)" in web.page.inner_text("#race-facts")
    web.screenshot("replay-finish")

    # scrubbing
    web.page.locator("#scrubber").fill(str(total // 2))
    assert viewer_step(web) == total // 2


def test_the_first_ten_cars_are_told_apart(web):
    web.goto("/replay")
    styles = web.page.evaluate("""async () => {
        const { carStyle } = await import("/static/js/palette.js");
        return [...Array(50).keys()].map(carStyle);
    }""")
    first = [(hex_rgb(style["color"]), style["shape"]) for style in styles[:10]]
    assert [color for color, _ in first] == [tuple(c) for c in render.CAR_COLORS]  # the toolkit's, as in its GIFs
    for (color1, shape1), (color2, shape2) in itertools.combinations(first, 2):
        assert delta_e(color1, color2) > CLEARLY_DIFFERENT, (color1, color2)
        if shape1 == shape2:  # then colour alone tells the cars apart: for red-green deficient eyes too
            for deficiency in DEFICIENCIES:
                assert delta_e(color1, color2, deficiency) > CLEARLY_DIFFERENT, (color1, color2, deficiency)
    assert len({(style["color"], style["shape"]) for style in styles}) == 50  # fifty cars, fifty markers


def test_outcomes_are_worded_as_the_toolkit_words_them(web):
    web.goto("/replay")
    texts = web.page.evaluate("""async (outcomes) => {
        const { finalText, outcomeText } = await import("/static/js/format.js");
        return [outcomes.map(outcomeText), finalText({ outcome: "off_road" }), outcomeText("running")];
    }""", list(OUTCOME_TEXT))
    assert texts == [list(OUTCOME_TEXT.values()), OUTCOME_TEXT["off_road"], "running"]


def test_replay_viewer_refuses_a_file_that_is_not_a_replay(web, tmp_path):
    path = tmp_path / "results.json"
    path.write_text(json.dumps({"episodes": []}))
    web.goto("/replay")
    web.page.set_input_files("#replay-file", str(path))
    web.page.wait_for_selector("#file-message.error")
    assert web.page.inner_text("#file-message") == \
        'results.json cannot be played: not a MicroRacer replay (no "format": "microracer-replay")'
    assert web.page.is_hidden("#viewer")


# --------------------------------------------------------------------------- instructor console


def test_instructor_creates_students_changes_settings_and_reruns(web, web_server, tmp_path):
    token = instructor_of_a_new_course(web_server)
    with web_server.client(token) as instructor:
        original = instructor.get("/api/settings/evaluation").json()
    web.login(token)
    assert web.page.url.endswith("/instructor")

    # Until the console knows who is logged in, its forms cannot be submitted. (They could: on a
    # busy machine a click came before the script was ready, the browser submitted the form
    # itself, reloaded the page as /instructor? and the token never appeared.)
    held = []
    web.page.route("**/api/users/me", lambda route: held.append(route))
    web.page.reload()
    assert web.page.is_disabled("#student-form button[type=submit]")
    assert web.page.is_disabled("#settings-form button[type=submit]")
    for route in held:
        route.continue_()
    web.page.unroute("**/api/users/me")  # lets through what it still held

    # one student: the token shown works
    name = unique("carol")
    web.page.fill("#student-name", name)
    web.page.click("#student-form button[type=submit]")
    web.page.wait_for_selector("#tokens:not([hidden])")
    token_shown = web.page.inner_text("#token-table tbody tr .token")
    assert web_server.client(token_shown).get("/api/users/me").json()["name"] == name
    assert web.page.url.endswith("/instructor")  # the script handled the form, not the browser

    # a roster as Excel saves it in much of Europe: semicolons, a BOM, CRLF
    roster = tmp_path / "roster.csv"
    first, second = unique("dan"), unique("eve")
    roster.write_bytes(f"\ufeffName;E-Mail\r\n{first};{first}@uni.de\r\n{second};{second}@uni.de\r\n".encode())
    web.page.set_input_files("#roster-file", str(roster))
    web.page.click("#roster-form button[type=submit]")
    web.page.wait_for_function(
        "() => document.querySelector('#students-message').textContent.includes('Created 2 students')")
    assert web.page.inner_text("#students-message") == \
        "Created 2 students from roster.csv (semicolon-separated, columns Name, E-Mail)."
    assert web.page.locator("#token-table tbody tr").count() == 3  # carol's stays until dismissed
    names = [text.splitlines() for text in web.page.locator("#users tbody td:first-child").all_inner_texts()]
    assert [first, f"{first}@uni.de"] in names and [second, f"{second}@uni.de"] in names  # the email under the name
    assert web.page.is_hidden("#roster-report")

    # the same roster again with a late enrolment and a bad line: the good line is created, the
    # enrolled students skipped, the bad line listed with its number
    late = unique("fay")
    roster.write_bytes(f"Name;E-Mail\n{first};{first}@uni.de\n{second};{second}@uni.de\n{late};{late}@uni.de\n"
                       f"=cmd|' /C calc'!A0;\n".encode())
    web.page.set_input_files("#roster-file", str(roster))
    web.page.click("#roster-form button[type=submit]")
    web.page.wait_for_function(
        "() => document.querySelector('#students-message').textContent.includes('Created 1 student ')")
    assert web.page.inner_text("#students-message") == (
        "Created 1 student from roster.csv (semicolon-separated, columns Name, E-Mail). Skipped 2 lines naming "
        "students already enrolled. 1 line with errors not created: fix them and upload the roster again.")
    assert web.page.locator("#students-message.error").count() == 1
    assert web.page.locator("#token-table tbody tr").all_inner_texts()[0].startswith(late)
    assert [row.split("\t") for row in web.page.locator("#roster-lines tbody tr").all_inner_texts()] == [
        ["2", first, "skipped", "already a student (same email)"],
        ["3", second, "skipped", "already a student (same email)"],
        ["5", "=cmd|' /C calc'!A0", "error", "the name \"=cmd|' /C calc'!A0\" holds '=': names are letters, digits, "
                                           "spaces, apostrophes, hyphens and . , _ @ +"]]

    # a workbook instead of a CSV file: what to do
    workbook = tmp_path / "roster.xlsx"
    workbook.write_bytes(b"PK\x03\x04" + bytes(60))
    web.page.set_input_files("#roster-file", str(workbook))
    web.page.click("#roster-form button[type=submit]")
    web.page.wait_for_function("() => document.querySelector('#students-message').textContent.includes('not read')")
    assert web.page.inner_text("#students-message") == (
        "The roster was not read: this is a spreadsheet workbook (.xlsx or .ods), not a CSV file: save it as "
        "CSV UTF-8 (Excel: File > Save As > CSV UTF-8) and upload that")
    assert web.page.is_hidden("#roster-report")

    # evaluation settings
    web.page.fill("#eval-episodes", "2")
    web.page.uncheck("#eval-obstacles")
    web.page.click("#settings-form button[type=submit]")
    web.page.wait_for_selector("#settings-message.success")
    with web_server.client(token) as instructor:
        saved = instructor.get("/api/settings/evaluation").json()
        ready = sum(s["status"] == "ready" for s in instructor.get("/api/submissions?all=true").json())
    assert saved == {**original, "episodes": 2, "env_options": {"obstacles": False}}
    assert web.page.inner_text("#settings-message") == (  # the course's students have none: the baselines
        f"Saved. {ready} submission{'s' if ready != 1 else ''} will be evaluated again with these settings, "
        "after the students' own uploads; until then their results show as stale.")

    # re-running every evaluation asks first, saying how many jobs and with which settings
    with web_server.client(token) as instructor:
        ready = sum(s["status"] == "ready" for s in instructor.get("/api/submissions?all=true").json())
    posts = []
    web.page.on("request", lambda request: posts.append(request.url) if request.method == "POST" else None)
    web.page.click("#rerun-all")
    web.page.wait_for_selector("#rerun-dialog[open]")
    submissions, jobs, evaluations = (f"{ready} {noun}{'s' if ready != 1 else ''}" for noun in
                                      ("ready submission", "job", "evaluation"))
    assert web.page.inner_text("#rerun-summary") == (
        f"This evaluates the {submissions} of the course again (the baselines' too), with the saved "
        f"settings: seed {saved['seed']}, 2 episodes, no obstacles. That is {jobs} for the workers.")
    web.screenshot("instructor-rerun-confirmation", full_page=False)
    web.page.click("#rerun-cancel")
    assert web.page.is_hidden("#rerun-dialog") and posts == []
    web.page.click("#rerun-all")
    web.page.locator("#rerun-confirm", has_text=f"Re-run {evaluations}").click()
    web.page.wait_for_function(
        "() => /Queued \\d+ evaluations?/.test(document.querySelector('#settings-message').textContent)")
    assert web.page.inner_text("#settings-message") == f"Queued {evaluations} with the current settings."
    web.page.wait_for_selector("#all-submissions tbody tr")
    web.screenshot("instructor-console")


def test_instructor_sets_a_rubric_and_sees_the_grades(web, web_server):
    """The console's Grades: an assignment's rubric (refused with the server's reason, then saved),
    its students' grades (none before the due time), the files to download."""
    token = instructor_of_a_new_course(web_server)
    with web_server.client(token) as instructor:
        student = instructor.post("/api/users", json={"name": unique("dora")}).json()
        assignment = instructor.post("/api/assignments", json={
            "name": "Time trial", "episodes": 3, "due_at": "2099-01-01T00:00:00+00:00"}).json()
    web.login(token)
    web.page.wait_for_selector("#grades-message.info")
    assert web.page.inner_text("#grades-message") == "Time trial has no rubric yet: edit the example above and save it."
    assert '"kind": "points"' in web.page.input_value("#rubric-text")  # an example to edit

    web.page.fill("#rubric-text", '{"kind": "formula", "max_points": 10, "formula": "10 * completed / mean_speed"}')
    web.page.click("#rubric-form button[type=submit]")
    web.page.wait_for_selector("#grades-message.error")
    assert web.page.inner_text("#grades-message") == ("Not saved: formula.formula: the formula divides by zero when "
                                                      "completed=0, mean_speed=0, rank=1, students=1")
    web.page.fill("#rubric-text", '{"kind": "formula", "max_points": 10, "formula": "10 * completed"}')
    web.page.click("#rubric-form button[type=submit]")
    web.page.wait_for_selector("#grades-message.success")
    web.page.wait_for_selector("#grades tbody tr")
    cells = web.page.locator("#grades tbody tr td").all_inner_texts()
    assert cells[:3] == ["–", student["name"], "not closed yet"] and cells[6] == "–"
    expect(web.page.locator("#grades-canvas-match")).to_have_text(  # created without ids: Canvas has only the name
        f"For Canvas: 0 of 1 rows carry an id Canvas matches (ID, SIS User ID or SIS Login ID); 1 only a name, "
        f"matched only if Canvas spells it the same: {student['name']}. Import Canvas's own gradebook export as "
        "the roster to carry its ids.")
    with web_server.client(token) as instructor:
        assert instructor.get(f"/api/assignments/{assignment['id']}").json()["rubric"]["formula"] == "10 * completed"
    with web.page.expect_download() as canvas:
        web.page.click("#grades-canvas")
    assert canvas.value.suggested_filename == "Time trial (Canvas).csv"
    assert Path(canvas.value.path()).read_text().startswith('Student,ID,SIS User ID,SIS Login ID,Section,Time trial\n')
    web.screenshot("instructor-grades")


def test_a_student_cannot_use_the_instructor_console(web, web_server):
    web.login(student_token(web_server, unique("frank")))
    web.goto("/instructor")
    web.page.wait_for_selector("#page-message.error")
    assert web.page.inner_text("#page-message").startswith("This page is for instructors")


# --------------------------------------------------------------------------- phone and projector


@pytest.mark.parametrize("width,height", [(390, 844), (1920, 1080)])
def test_pages_fit_phones_and_projectors(web, replay_file, width, height):
    web.page.set_viewport_size({"width": width, "height": height})
    for path in ("/", "/login", "/replay"):
        web.goto(path)
        if path == "/replay":
            web.page.set_input_files("#replay-file", str(replay_file[0]))
            web.page.wait_for_selector("#viewer:not([hidden])")
            web.page.keyboard.press("End")
        overflow = web.page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
        assert overflow <= 0, f"{path} is {overflow} px wider than a {width} px screen"
        web.screenshot(f"{path.strip('/') or 'leaderboard'}-{width}px")
    canvas = web.page.locator("#race-canvas").bounding_box()
    assert canvas["width"] <= width and canvas["height"] <= height


def test_controls_have_accessible_names(web):
    web.goto("/replay")
    unnamed = web.page.evaluate("""() => [...document.querySelectorAll('button, input, select, a[href]')]
        .filter((el) => !el.hidden && !(el.labels && el.labels.length) && !el.getAttribute('aria-label')
                        && !el.textContent.trim() && !el.querySelector('img[alt]:not([alt=""])'))
        .map((el) => el.outerHTML)""")
    assert unnamed == []


# --------------------------------------------------------------------------- leaderboard, races, rounds


def ready_submission(server, token: str, path) -> int:
    client = server.client(token)
    response = upload(client, path)
    assert response.status_code == 201, response.text
    result = wait_settled(client, response.json()["id"])
    assert result["status"] == "ready" and result["evaluation"]["status"] == "done", result
    return result["id"]


def test_student_sees_their_agent_on_the_leaderboard(web, web_server, agent_files):
    name = unique("gina")
    token = student_token(web_server, name)
    ready_submission(web_server, token, agent_files["driver_0.3"])
    # The public cache first serves what it kept, then refreshes (league/server/api/cache.py): after
    # another test loaded the page, the new row came only with the page's refresh 15 s later.
    wait_for(lambda: web_server.client(token).get("/api/leaderboard?page=1&size=50").json()["items"],
             lambda rows: any(row["owner"] == name for row in rows))
    web.login(token)

    web.goto("/")
    own = web.page.locator("#leaderboard tbody tr.own")
    own.wait_for()
    assert name in own.inner_text()
    assert web.page.is_hidden("#leaderboard-csv") and web.page.is_hidden("#standings-csv")  # grades: instructors
    # sortable, best first on the first click, and saying which way is better
    header = web.page.locator("#leaderboard th", has_text="Mean return")
    assert "higher is better" in header.inner_text()
    header.locator(".better").click()  # the hint is part of the header's button, not a chip beside it
    assert header.get_attribute("aria-sort") == "descending"
    returns = [float(t) for t in web.page.locator("#leaderboard tbody tr td:nth-child(5)").all_inner_texts()]
    assert returns == sorted(returns, reverse=True)
    web.screenshot("leaderboard-own-row")


def test_a_settings_change_shows_every_earlier_result_apart_as_stale(web, web_server):
    with web_server.client(web_server.instructor_token) as instructor:
        before = instructor.get("/api/settings/evaluation").json()
        try:  # re-evaluations of 1000 episodes: none is over while the page is read
            changed = instructor.put("/api/settings/evaluation",
                                     json={**before, "seed": before["seed"] + 1, "episodes": 1000})
            assert changed.status_code == 200 and changed.json()["reevaluating"], changed.text
            reader = student_token(web_server, unique("reader"))  # the board is the members' (the default)
            web.login(reader)
            web.goto("/")
            stale = web.page.locator("#leaderboard tbody tr.apart")
            stale.first.wait_for()
            # as the page (that student)
            board = web_server.client(reader).get("/api/leaderboard?page=1&size=50").json()["items"]
            assert board and all(row["stale"] and row["rank"] is None for row in board)
            assert stale.count() == web.page.locator("#leaderboard tbody tr").count() == len(board)
            assert stale.locator("td:first-child .badge.stale").count() == len(board)
            assert [text.split("\t")[1] for text in stale.all_inner_texts()] == [row["owner"] for row in board]
            web.screenshot("leaderboard-stale-rows")
        finally:  # back, and the re-evaluation a worker started stopped
            instructor.put("/api/settings/evaluation", json=before)
            for job in instructor.get("/api/jobs", params={"status": "running"}).json():
                if job["priority"] == 1:
                    instructor.post(f"/api/jobs/{job['id']}/cancel")


def tie_break(row: dict, above: dict | None) -> str | None:
    """What ranks `row` below `above` when their points are level: wins, then 2nd places, ..."""
    if above is None or above["points"] != row["points"]:
        return None
    for position in range(1, max(row["finishes"] + above["finishes"]) + 1):
        if row["finishes"].count(position) != above["finishes"].count(position):
            what = "wins" if position == 1 else f"{render.ordinal(position)} places"
            return f"level on points with rank {above['rank']}: fewer {what}"
    return f"level with rank {above['rank']} on points and finishes"


def test_instructor_runs_a_round_opens_a_replay_and_the_standings_break_ties(web, web_server, agent_files):
    """The console's championship path at the default board visibility (members: issue 30, the panel
    read its championships without the token), then a student sees the standings."""
    racers = [student_token(web_server, unique("racer")) for _ in range(2)]
    for token, speed in zip(racers, ("0.2", "0.25")):
        ready_submission(web_server, token, agent_files[f"driver_{speed}"])
    with web_server.client(web_server.instructor_token) as instructor:
        assert instructor.get("/api/settings/privacy").json()["board_visibility"] == "members"
    web.login(web_server.instructor_token)

    web.page.click("#new-championship summary")
    championship = unique("Cup")
    web.page.fill("#champ-name", championship)
    web.page.fill("#champ-heat", "4")
    web.page.fill("#champ-seed", "11")  # reproducible heats (the track is drawn secretly)
    web.page.fill("#champ-points", "10, 10")  # every heat's first two level on points: ties to break
    web.page.click("#championship-form button[type=submit]")
    expect(web.page.locator("#championships-message")).to_have_text(f"Created the championship “{championship}”.")
    card = web.page.locator("[data-championship]", has_text=championship)
    championship_id = card.get_attribute("data-championship")
    card.locator("button", has_text="Run round 1").click()
    card.locator("[data-round='1'] progress").wait_for()
    web.screenshot("instructor-round-running")
    card.locator("[data-round='1'] .badge.done").wait_for(timeout=120_000)
    web.screenshot("instructor-round-done")

    card.locator("[data-round='1'] a", has_text="Heat 1").click()
    web.page.wait_for_url(re.compile(r"/races/\d+$"))
    web.page.wait_for_selector("#viewer:not([hidden])")
    first = canvas_pixels(web, "#race-canvas")
    web.page.wait_for_function("() => Number(document.querySelector('#viewer').dataset.step) > 30")
    # "Link to this moment" follows the step on screen while it plays
    step, link = web.page.evaluate("() => [document.querySelector('#viewer').dataset.step, "
                                   "document.querySelector('#share-link').value]")
    assert web.page.is_visible("#share-link") and link.endswith(f"?step={step}"), (step, link)
    web.page.click("#play-button")  # pause
    on_track = colors_on_track(web_server, web.page.url, viewer_step(web))
    assert on_track, "no car of the first four is still racing: the heat does not show the viewer"
    assert_drawn(canvas_pixels(web, "#race-canvas", on_track), on_track)
    assert canvas_pixels(web, "#race-canvas")["hash"] != first["hash"]
    web.screenshot("race-replay")

    # a shareable link opens at its step, paused
    race_path = web.page.url.split("?")[0].replace(web.base, "")
    web.goto(f"{race_path}?step=50")
    web.page.wait_for_selector("#viewer:not([hidden])")
    assert viewer_step(web) == 50
    web.page.wait_for_timeout(300)
    assert viewer_step(web) == 50 and web.page.inner_text("#play-button") == "Play"

    # the standings say what broke each tie on points
    web.goto(f"/?championship={championship_id}")
    rows = web_server.client(web_server.instructor_token).get(
        f"/api/championships/{championship_id}/standings").json()["items"]
    web.page.wait_for_selector(f"#standings tbody tr[data-key='{rows[-1]['submission_id']}']")
    notes = [tie_break(row, above) for above, row in zip([None] + rows, rows)]
    for row, note in zip(rows, notes):
        points = web.page.inner_text(f"#standings tbody tr[data-key='{row['submission_id']}'] td:nth-child(4)")
        assert points.split("\n") == [str(row["points"])] + ([note] if note else []), (row, points)
    assert any(notes), f"no tie on points in {rows}"
    web.screenshot("standings-tie-breaks")

    # the instructor downloads the grades: the server's CSV, read back
    for button, path in (("#standings-csv", f"/api/championships/{championship_id}/standings.csv"),
                         ("#leaderboard-csv", "/api/leaderboard.csv")):
        with web.page.expect_download() as event:
            web.page.click(button)
        saved = Path(event.value.path()).read_text()
        served = web_server.client(web_server.instructor_token).get(path).text
        assert list(csv.DictReader(io.StringIO(saved))) == list(csv.DictReader(io.StringIO(served)))
        assert saved.startswith("rank,student,agent,submission_id,")

    web.login(racers[0])  # a student of the course: the standings, at the default visibility
    web.goto(f"/?championship={championship_id}")
    web.page.wait_for_selector(f"#standings tbody tr[data-key='{rows[0]['submission_id']}']")
    assert web.page.is_hidden("#board-closed")


def test_the_automatic_assignment_closes_once_the_instructor_makes_one_and_the_upload_asks_which(
        web, web_server, agent_files):
    """Issue 30: the console says what becomes of the automatic assignment and keeps it open on request;
    with several open the student's upload names one (a picker with nothing chosen, no upload sent
    before they choose); with one open there is nothing to choose."""
    token = instructor_of_a_new_course(web_server)
    with web_server.client(token) as instructor:
        student = instructor.post("/api/users", json={"name": unique("picker")}).json()
        [automatic] = instructor.get("/api/assignments").json()
    web.login(token)
    web.goto("/instructor")
    line = web.page.locator(f"#assignments tr[data-assignment='{automatic['id']}']")
    expect(line).to_contain_text("(automatic: takes uploads until you create an assignment)")
    web.page.fill("#assignment-name", "Sprint")
    web.page.click("#assignment-form button[type=submit]")
    expect(web.page.locator("#assignment-message")).to_have_text(
        "Created Sprint. The automatic assignment default no longer takes uploads (tick “Keep open” on its line "
        "to keep it).")
    expect(line).to_contain_text("(automatic: closed to uploads: your assignments replaced it)")
    web.page.check(f"#keep-open-{automatic['id']}")
    expect(web.page.locator("#assignment-message")).to_have_text(
        "default keeps taking uploads beside your assignments.")
    expect(line).to_contain_text("(automatic: kept open beside your assignments)")
    with web_server.client(token) as instructor:
        listed = {a["name"]: a for a in instructor.get("/api/assignments").json()}
    assert listed["default"]["keep_open"] is True
    web.screenshot("console-automatic-assignment-kept-open")

    web.login(student["token"])
    web.goto("/submissions")
    picker = web.page.locator("#upload-assignment")
    expect(picker).to_be_visible()
    expect(picker).to_have_value("")
    assert picker.locator("option").all_inner_texts() == ["Choose the assignment…", "default", "Sprint"]
    web.drop_file("#drop-zone", agent_files["driver_0.25"])
    web.page.click("#upload-button")
    expect(web.page.locator("#upload-message")).to_have_text(
        "Several assignments are open (default, Sprint): choose the one this upload is for.")
    expect(picker).to_be_focused()
    with web_server.client(student["token"]) as client:
        assert client.get("/api/submissions").json() == []  # nothing was sent
    picker.select_option(label="Sprint")
    with web.page.expect_response(lambda r: r.url.endswith("/api/submissions") and r.request.method == "POST") as sent:
        web.page.click("#upload-button")
    assert sent.value.status == 201
    with web_server.client(student["token"]) as client:
        [mine] = client.get("/api/submissions").json()
    assert mine["assignment_id"] == listed["Sprint"]["id"]
    expect(picker).to_have_value(str(listed["Sprint"]["id"]))  # the choice stays, shown, for the next upload

    with web_server.client(token) as instructor:  # closed again: one is open, the server takes it
        assert instructor.patch(f"/api/assignments/{automatic['id']}", json={"keep_open": False}).status_code == 200
    web.page.reload()
    web.page.locator("#assignments tbody tr", has_text="Sprint").wait_for()
    expect(picker).to_be_hidden()


def test_student_starts_a_friendly_race_against_the_baselines(web, web_server, agent_files):
    token = student_token(web_server, unique("hank"))
    ready_submission(web_server, token, agent_files["driver_0.25"])
    web.login(token)

    baseline = web.page.locator("#opponents label", has_text="(baselines)").first
    baseline.wait_for()
    assert baseline.locator("input").is_checked()
    web.page.click("#race-button")
    link = web.page.locator("#race-message a", has_text="Watch the race")
    link.wait_for()
    link.click()
    web.page.wait_for_selector("#viewer:not([hidden])", timeout=90_000)
    assert web.page.locator("#car-legend li").count() >= 2
    web.screenshot("friendly-race")


def test_student_picks_the_active_submission(web, web_server, agent_files):
    token = student_token(web_server, unique("iris"))
    older = ready_submission(web_server, token, agent_files["driver_0.2"])
    ready_submission(web_server, token, agent_files["driver_0.3"])
    web.login(token)

    web.page.locator(f"#submissions tr[data-id='{older}'] button", has_text="Make active").click()
    web.page.locator(f"#submissions tr[data-id='{older}'] .badge.active").wait_for()
    assert wait_for(lambda: web_server.client(token).get(f"/api/submissions/{older}").json(),
                    lambda s: s.get("active") is True)


def test_instructor_deletes_a_student_after_a_confirmation_and_reads_it_in_the_audit_log(web, web_server):
    token = instructor_of_a_new_course(web_server)
    name = unique("dee")
    with web_server.client(token) as instructor:
        student = instructor.post("/api/users", json={"name": name}).json()
    web.login(token)
    delete = f"#users [data-focus-key='delete-{student['id']}']"
    expect(web.page.locator(delete)).to_have_accessible_name(f"Delete {name} and their data")

    web.page.click(delete)  # asks first: cancelling keeps the student
    web.page.wait_for_selector("#delete-dialog[open]")
    expect(web.page.locator("#delete-title")).to_have_text(f"Delete {name} and their data?")
    web.page.click("#delete-dialog button[value=cancel]")
    assert web_server.client(student["token"]).get("/api/users/me").status_code == 200

    web.page.click(delete)
    web.page.click("#delete-dialog button[value=delete]")
    expect(web.page.locator("#students-message")).to_have_text(f"{name} and their data are deleted.")
    expect(web.page.locator(delete)).to_have_count(0)
    assert web_server.client(student["token"]).get("/api/users/me").status_code == 401

    web.page.click("#refresh-audit")
    newest = web.page.locator("#audit tbody tr").first
    expect(newest).to_contain_text("user.delete")
    expect(newest).to_contain_text(f"user #{student['id']}")
    expect(web.page.locator("#audit")).not_to_contain_text(name)  # the deleted student's name is not kept


def test_a_board_for_members_prompts_a_visitor_to_log_in_and_a_student_picks_a_display_name(web, web_server):
    token = student_token(web_server, unique("hana"))
    with web_server.client(web_server.instructor_token) as instructor:  # the default: nothing to set
        assert instructor.get("/api/settings/privacy").json()["board_visibility"] == "members"
    web.goto("/")
    prompt = web.page.locator("#board-closed")
    prompt.wait_for()
    assert prompt.inner_text().startswith("Log in to see the boards. The server says: log in to see this: "
                                          "the boards of course 'default' are shown to the course's students")
    assert web.page.is_hidden("#leaderboard") and web.page.is_hidden("#standings")  # no empty tables
    web.screenshot("board-login-prompt")
    prompt.locator("a").click()
    web.page.wait_for_url("**/login?next=%2F")

    web.login(token)
    web.goto("/")
    web.page.locator("#leaderboard").wait_for()
    assert web.page.is_hidden("#board-closed")

    web.goto("/submissions")
    expect(web.page.locator("#display-note")).to_contain_text("shown to its students and instructors only")
    web.page.fill("#display-name", "Student 7")
    web.page.click("#display-form button[type=submit]")
    expect(web.page.locator("#display-message")).to_contain_text("Not saved: the display name 'Student 7' "
                                                                 "looks like the pseudonym")
    web.page.fill("#display-name", unique("Comet"))
    web.page.click("#display-form button[type=submit]")
    expect(web.page.locator("#display-message")).to_contain_text("Saved: visitors of public boards see")


def test_a_student_selects_a_final_submission_then_sees_the_private_result_and_grade(web, web_server, agent_files):
    """The student's Assignments table: their best on the public board until they select another on
    the page (the API then shows that selection); nothing private before publication (the grade is
    not even asked for); once the instructor publishes, the private result and their grade."""
    token = instructor_of_a_new_course(web_server)  # publication waits for every student of the course
    with web_server.client(token) as instructor:
        student = instructor.post("/api/users", json={"name": unique("sel")}).json()
        sprint = instructor.post("/api/assignments", json={"name": "Sprint", "episodes": 2,
                                                            "due_at": "2099-01-01T00:00:00+00:00"}).json()
        assert instructor.put(f"/api/assignments/{sprint['id']}/rubric", json={
            "kind": "formula", "max_points": 10, "formula": "10 * completed"}).status_code == 200
    ids = []
    with web_server.client(student["token"]) as client:
        for speed in ("0.2", "0.3"):
            with open(agent_files[f"driver_{speed}"], "rb") as handle:
                response = client.post("/api/submissions", files={"file": ("agent.onnx", handle)},
                                       data={"name": f"driver {speed}", "assignment": str(sprint["id"])})
            assert response.status_code == 201, response.text
            ids.append(wait_settled(client, response.json()["id"])["id"])
        best = client.get(f"/api/assignments/{sprint['id']}").json()["final"]["submission_id"]
    chosen = next(i for i in ids if i != best)
    names = {ids[0]: "driver 0.2", ids[1]: "driver 0.3"}

    web.login(student["token"])
    web.goto("/submissions")
    row = web.page.locator("#assignments tbody tr", has_text="Sprint")
    expect(row).to_contain_text(f"best on the public board: {names[best]}")
    expect(row).to_contain_text("after publication")
    web.page.select_option(f"#final-{sprint['id']}", str(chosen))
    web.page.get_by_role("button", name="Select: the final submission of Sprint").click()
    expect(web.page.locator("#assignment-message")).to_have_text(f"{names[chosen]} is your final submission of Sprint.")
    expect(row).to_contain_text(f"{names[chosen]} (selected)")
    expect(web.page.get_by_role("button", name="Select: the final submission of Sprint")).to_be_focused()
    with web_server.client(student["token"]) as client:
        final = client.get(f"/api/assignments/{sprint['id']}").json()["final"]
    assert (final["submission_id"], final["selected"]) == (chosen, True)
    assert not [url for url in web.requests if "/grades/me" in url]  # not published: not asked

    with web_server.client(token) as instructor:  # the due time passes: the finals are frozen and tested privately
        assert instructor.patch(f"/api/assignments/{sprint['id']}",
                                json={"due_at": "2020-01-01T00:00:00+00:00"}).status_code == 200
        rows = wait_for(lambda: instructor.get(f"/api/assignments/{sprint['id']}/grades").json()["rows"],
                        lambda rows: [r["status"] for r in rows if r["role"] == "student"] == ["graded"], timeout=120)
        assert instructor.post(f"/api/assignments/{sprint['id']}/publish").status_code == 200
    graded = next(r for r in rows if r["role"] == "student")
    with web_server.client(student["token"]) as client:
        mine = client.get(f"/api/assignments/{sprint['id']}").json()["final"]["evaluation"]
    web.page.reload()
    expect(row).to_contain_text(f"{names[chosen]} (selected), frozen")
    expect(row).to_contain_text(f"{mine['completed']}/{mine['episodes_total']} laps, return {mine['mean_return']:.2f}; "
                                f"grade {graded['points']:.1f} of 10.0, rank 1 of 1")
    assert graded["submission_id"] == chosen
    web.screenshot("student-final-and-grade")
