"""The LMS round trip, in process on both backends: the roster imported from Canvas's gradebook export
and Moodle's participants export as those systems write them, their ids kept; the grade files echo
them, Canvas's with its "Last, First" names; the Canvas match counts (the console's preview and
`league grades --check`) say who carries an id Canvas matches.

The files are shaped as the systems write them (docs: the server README's "Grades"):
- Canvas, Grades > Export: a UTF-8 BOM; `Student, ID, SIS User ID, SIS Login ID, Section`, one
  column an assignment titled "Name (id)", the read-only score columns; then "Points Possible"
  (indented, "(read only)" under the scores), the posting-policy line, a line a student with the
  name "Last, First", and the Test Student of Canvas's Student View (canvas-lms GradebookImporter
  reads the same lines).
- Moodle, Participants > With selected users > Download (user/action_redir.php): `First name, Last
  name, Email address` and the site's identity fields (`ID number`).
"""
from __future__ import annotations

import csv
import io
import random
import uuid

import pytest

from league.server.db.models import INSTRUCTOR

from ...api_calls import unique


def post_roster(client, data: bytes | str):
    data = data.encode() if isinstance(data, str) else data
    return client.post("/api/users/roster", files={"file": ("export.csv", data, "text/csv")})


def lines(report: list[dict]) -> list[tuple]:
    return [(line["line"], line["name"], line["reason"]) for line in report]


def rows_of(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


def canvas_export(tag: str, ids: list[str]) -> bytes:
    """Canvas's gradebook export of a course of two students, its Test Student and one assignment."""
    return ("\ufeffStudent,ID,SIS User ID,SIS Login ID,Section,Sprint (81723),Current Score,Unposted Current Score,"
            "Final Score,Unposted Final Score\r\n"
            "    Points Possible,,,,,10.00,(read only),(read only),(read only),(read only)\r\n"
            ",,,,,Manual Posting,,,,\r\n"
            f'"Lovelace{tag}, Ada",{ids[0]},S1-{tag},alovelace{tag},CS 101 Section 1,8.00,80.00,80.00,80.00,80.00\r\n'
            f'"O\'Brien{tag}, Niaj",{ids[1]},S2-{tag},nobrien{tag},CS 101 Section 2,,,,,\r\n'
            f'"Student, Test",{ids[2]},,{tag}testuser,CS 101 Section 1,,,,,\r\n').encode()


def moodle_participants(tag: str) -> bytes:
    """Moodle's participants download (CSV dataformat): UTF-8 with a BOM, the identity fields last."""
    return ("\ufeffFirst name,Last name,Email address,ID number\n"
            f"José,García{tag},jose.{tag}@uni.es,M1-{tag}\n"
            f"Zoë,Müller{tag},zoe.{tag}@uni.de,M2-{tag}\n").encode()


@pytest.fixture
def course(app_league):
    """An instructor of a course of their own (the grade files list only its students)."""
    _, token = app_league.user("prof", role=INSTRUCTOR, course_name=unique("course"))
    with app_league.client(token) as instructor:
        yield instructor


def graded_assignment(instructor) -> dict:
    assignment = instructor.post("/api/assignments", json={"name": "Sprint", "episodes": 2,
                                                           "due_at": "2099-01-01T00:00:00+00:00"}).json()
    rubric = {"kind": "formula", "max_points": 10, "formula": "10 * completed"}
    assert instructor.put(f"/api/assignments/{assignment['id']}/rubric", json=rubric).status_code == 200
    return assignment


def test_the_canvas_export_is_a_roster_and_the_canvas_file_echoes_its_ids_and_names(course):
    tag, ids = uuid.uuid4().hex[:6], [str(random.randrange(10**9, 10**10)) for _ in range(3)]
    report = post_roster(course, canvas_export(tag, ids))
    assert report.status_code == 201, report.text
    report = report.json()
    assert report["format"] == {"delimiter": "comma", "layout": "canvas", "columns": {
        "full": "Student", "canvas_id": "ID", "student_id": "SIS User ID", "sis_login_id": "SIS Login ID"}}
    assert [(u["name"], u["canvas_id"], u["student_id"], u["sis_login_id"], u["email"]) for u in report["created"]] == [
        (f"Ada Lovelace{tag}", ids[0], f"S1-{tag}", f"alovelace{tag}", None),
        (f"Niaj O'Brien{tag}", ids[1], f"S2-{tag}", f"nobrien{tag}", None)]
    assert lines(report["skipped"]) == [
        (2, None, "Canvas's Points Possible line (each assignment's maximum), not a student"),
        (3, None, "Canvas's line of grade posting policies, not a student"),
        (6, None, "Canvas's Test Student (the account of its Student View), not a person")]
    assert report["errors"] == []

    course.post("/api/users", json={"name": f"Grace Hopper{tag}", "email": f"grace.{tag}@uni.edu"})
    course.post("/api/users", json={"name": f"Alan Turing{tag}"})
    assignment = graded_assignment(course)
    text = course.get(f"/api/assignments/{assignment['id']}/grades.csv", params={"format": "canvas"}).text
    table = rows_of(text)
    assert table[:2] == [["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "Sprint"],
                         ["Points Possible", "", "", "", "", "10.0"]]
    assert table[2:] == [  # in the order of their names; grades empty until the due time
        [f"Lovelace{tag}, Ada", ids[0], f"S1-{tag}", f"alovelace{tag}", "", ""],
        [f"Turing{tag}, Alan", "", "", "", "", ""],
        [f"Hopper{tag}, Grace", "", "", f"grace.{tag}@uni.edu", "", ""],
        [f"O'Brien{tag}, Niaj", ids[1], f"S2-{tag}", f"nobrien{tag}", "", ""]]

    match = course.get(f"/api/assignments/{assignment['id']}/grades/canvas-match").json()
    assert (match["students"], match["by_id"], match["by_email"], match["by_name"]) == (
        4, [f"Ada Lovelace{tag}", f"Niaj O'Brien{tag}"], [f"Grace Hopper{tag}"], [f"Alan Turing{tag}"])
    assert match["summary"].startswith("2 of 4 rows carry an id Canvas matches (ID, SIS User ID or SIS Login ID); "
                                       "1 only an email as SIS Login ID")
    assert course.get("/api/grades/canvas-match").json() == match  # the course's file: the same students


def test_the_canvas_export_again_records_the_ids_of_students_enrolled_by_name(course):
    tag, ids = uuid.uuid4().hex[:6], [str(random.randrange(10**9, 10**10)) for _ in range(3)]
    post_roster(course, f"name\nAda Lovelace{tag}\n")
    again = post_roster(course, canvas_export(tag, ids)).json()
    assert [u["name"] for u in again["created"]] == [f"Niaj O'Brien{tag}"]
    assert lines(again["skipped"])[2] == (
        4, f"Ada Lovelace{tag}", "already a student (same name); their student id and Canvas ID and SIS Login ID "
                                 "recorded")
    once_more = post_roster(course, canvas_export(tag, ids)).json()  # found by their Canvas ID now
    assert once_more["created"] == [] and lines(once_more["skipped"])[2][2] == "already a student (same Canvas ID)"
    users = {u["name"]: u for u in course.get("/api/users").json()}
    assert (users[f"Ada Lovelace{tag}"]["canvas_id"], users[f"Ada Lovelace{tag}"]["sis_login_id"]) == (
        ids[0], f"alovelace{tag}")


def test_a_canvas_line_whose_ids_belong_to_another_student_is_refused(course):
    tag, ids = uuid.uuid4().hex[:6], [str(random.randrange(10**9, 10**10)) for _ in range(3)]
    post_roster(course, canvas_export(tag, ids))
    swapped = canvas_export(tag, [ids[1], ids[0], ids[2]])  # Ada's line with Niaj's Canvas ID
    report = post_roster(course, swapped).json()
    assert report["created"] == [] and [error["line"] for error in report["errors"]] == [4, 5]
    assert "its Canvas ID is that of" in report["errors"][0]["reason"]


def test_the_moodle_participants_export_is_a_roster_and_the_moodle_file_echoes_its_id_numbers(course):
    tag = uuid.uuid4().hex[:6]
    report = post_roster(course, moodle_participants(tag)).json()
    assert report["format"] == {"delimiter": "comma", "layout": "plain", "columns": {
        "first": "First name", "last": "Last name", "email": "Email address", "student_id": "ID number"}}
    assert [(u["name"], u["email"], u["student_id"]) for u in report["created"]] == [
        (f"José García{tag}", f"jose.{tag}@uni.es", f"M1-{tag}"),
        (f"Zoë Müller{tag}", f"zoe.{tag}@uni.de", f"M2-{tag}")]
    assignment = graded_assignment(course)
    by_id = course.get(f"/api/assignments/{assignment['id']}/grades.csv",
                       params={"format": "moodle", "identifier": "idnumber"})
    assert rows_of(by_id.text) == [["ID number", "Sprint"], [f"M1-{tag}", ""], [f"M2-{tag}", ""]]
    by_email = course.get(f"/api/assignments/{assignment['id']}/grades.csv", params={"format": "moodle"})
    assert rows_of(by_email.text)[1:] == [[f"jose.{tag}@uni.es", ""], [f"zoe.{tag}@uni.de", ""]]
    assert by_id.headers["X-Left-Out"] == by_email.headers["X-Left-Out"] == "0"


@pytest.mark.parametrize("cell, reason", [
    ("12ab", "the Canvas ID '12ab' is not a Canvas user ID"),
    ("=1+1", "the Canvas ID '=1+1' is not a Canvas user ID"),
])
def test_a_canvas_id_that_is_not_a_canvas_user_id_is_refused(course, cell, reason):
    text = f'Student,ID,SIS User ID,SIS Login ID,Section\n"Smith, Jo",{cell},,,A\n'
    report = post_roster(course, text).json()
    assert report["created"] == [] and report["errors"][0]["reason"].startswith(reason)
