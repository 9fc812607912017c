"""The integrity report's page (/integrity) in a real browser: what an instructor sees of two
students who uploaded one file, the CSV it downloads, axe's WCAG 2.1 AA rules, and a student
turned away."""
from __future__ import annotations

import csv
import io

from playwright.sync_api import expect

from league.server.course.integrity import CSV_COLUMNS

from ...server.api_calls import unique, upload, wait_for
from ..servers import instructor_of_a_new_course
from .axe import Audit
from .browsing import require_browser

require_browser()


def test_an_instructor_sees_two_students_with_one_file(web, web_server, agent_files):
    instructor = instructor_of_a_new_course(web_server)
    names = [unique("ann"), unique("bob")]
    with web_server.client(instructor) as prof:
        tokens = [prof.post("/api/users", json={"name": name}).json()["token"] for name in names]
    for token in tokens:
        with web_server.client(token) as student:
            sent = upload(student, agent_files["driver_0.2"]).json()["id"]
            wait_for(lambda: student.get(f"/api/submissions/{sent}").json()["status"], lambda s: s == "ready")  # noqa: B023 - called in this iteration

    web.login(instructor)
    web.goto("/integrity")
    row = web.page.locator("#integrity-groups tbody tr", has_text="Identical file")
    expect(row).to_have_count(1)
    expect(row.locator("td").nth(2)).to_have_text(", ".join(sorted(names)))
    expect(web.page.locator("#integrity-summary")).to_contain_text("1 group")
    audit = Audit(web)
    audit.check("a group")
    audit.assert_clean()
    with web.page.expect_download() as download:
        web.page.click("#integrity-csv")
    rows = list(csv.DictReader(io.StringIO(open(download.value.path(), encoding="utf-8").read())))
    grouped = [r for r in rows if r["kind"] != "not_compared"]  # then those not yet on the secret set
    assert list(rows[0]) == CSV_COLUMNS and sorted(r["owner"] for r in grouped) == sorted(names)

    web.login(tokens[0])
    web.goto("/integrity")
    expect(web.page.locator("#page-message")).to_contain_text("This page is for instructors")
