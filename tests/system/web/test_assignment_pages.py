"""Assignments on the student's page, in a real browser against the real server: the time left is
rounded down honestly (the last minute is "under a minute", the late window says so); a late upload
is said late. (Publishing after a confirmation: test_accessibility.py, by keyboard.)"""
from __future__ import annotations

import re
from datetime import datetime, timedelta, timezone

from playwright.sync_api import expect

from ...server.api_calls import unique
from ..servers import instructor_of_a_new_course
from .browsing import require_browser

require_browser()


def test_time_left_is_rounded_down_and_the_last_minute_is_under_a_minute(web):
    web.goto("/login")
    said = web.page.evaluate("""async () => {
        const { timeLeft, uploadTimeLeft } = await import("/static/js/format.js");
        const now = "2026-12-01T12:00:00+00:00";
        const a = { now, my_due_at: "2026-12-01T11:00:00+00:00", my_closes_at: "2026-12-01T12:00:30+00:00" };
        return [timeLeft("2026-12-01T12:00:59+00:00", now), timeLeft("2026-12-01T12:01:00+00:00", now),
                timeLeft("2026-12-03T13:30:00+00:00", now), timeLeft(now, now), timeLeft(null, now),
                uploadTimeLeft({ ...a, state: "late" }), uploadTimeLeft({ ...a, state: "closed" }),
                uploadTimeLeft({ ...a, state: "open", my_due_at: "2026-12-01T12:00:01+00:00" })];
    }""")
    assert said == ["under a minute", "0 h 1 min", "2 d 1 h", "passed", "no deadline",
                    "due time passed; late uploads: under a minute left", "closed", "under a minute"]


def test_a_late_upload_is_said_late_in_the_list_and_its_details(web, web_server, agent_files):
    instructor = instructor_of_a_new_course(web_server)
    now = datetime.now(timezone.utc)
    name = unique("Late lap")
    with web_server.client(instructor) as client:
        client.post("/api/assignments", json={"name": name, "episodes": 2,
                                              "due_at": (now - timedelta(minutes=5)).isoformat(),
                                              "late_until": (now + timedelta(hours=2)).isoformat()})
        student = client.post("/api/users", json={"name": unique("tardy")}).json()
        open_lap = unique("Open lap")  # no due time: where an on-time upload goes
        assert client.post("/api/assignments", json={"name": open_lap, "episodes": 2}).status_code == 201
    with web_server.client(student["token"]) as client, open(agent_files["driver_0.2"], "rb") as handle:
        late = client.post("/api/submissions", files={"file": ("late.onnx", handle)},
                           data={"name": "late lap", "assignment": name}).json()
        on_time = client.post("/api/submissions", files={"file": ("driver.onnx", b"not a model")},
                              data={"name": "on time", "assignment": open_lap}).json()
    web.login(student["token"])
    web.goto(f"/submissions?id={late['id']}")
    late_row = web.page.locator(f"#submissions tr[data-id='{late['id']}']")
    expect(late_row.locator(".badge.late")).to_have_text("late")
    expect(web.page.locator(f"#submissions tr[data-id='{on_time['id']}'] .badge.late")).to_have_count(0)
    expect(web.page.locator("#detail-title .badge.late")).to_have_text("late")
    expect(web.page.locator("#detail-facts")).to_contain_text("(late: after your due time)")
    row = web.page.locator("#assignments tbody tr", has_text=name)
    expect(row.locator("td").nth(4)).to_have_text(re.compile(r"due time passed; late uploads: 1 h 5\d min left"))
