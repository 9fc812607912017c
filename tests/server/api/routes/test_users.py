"""Accounts, in process on both backends: instructors create students (one or a CSV roster) and revoke them."""
from __future__ import annotations

import os
import subprocess
import sys
import uuid

import pytest

from league.server.db.models import REJECTED

from ...api_calls import create_student, unique, upload


def test_cli_token_authenticates_the_instructor(app_league):
    """`league users add` writes to the same database as the app; its token is accepted."""
    env = {**os.environ, "LEAGUE_DATABASE_URL": app_league.settings.resolved_database_url,
           "LEAGUE_DATA_DIR": str(app_league.settings.data_dir)}
    name = unique("prof")
    added = subprocess.run([sys.executable, "-m", "league.server", "users", "add", name, "--role", "instructor"],
                           env=env, capture_output=True, text=True, timeout=120)
    assert added.returncode == 0, added.stderr
    with app_league.client(added.stdout.strip()) as instructor:
        me = instructor.get("/api/users/me")
    assert me.status_code == 200
    assert (me.json()["name"], me.json()["role"], me.json()["active"]) == (name, "instructor", True)


def test_instructor_creates_a_student_whose_token_works(app_league):
    name, tag = unique("carol"), uuid.uuid4().hex[:8]
    with app_league.client(app_league.instructor_token) as instructor:
        created = instructor.post("/api/users", json={"name": name, "email": f"carol.{tag}@Uni.EDU",
                                                      "student_id": f"s{tag}"})
        assert created.status_code == 201
        assert created.json()["token"].startswith("lg_") and created.json()["role"] == "student"
        assert (created.json()["email"], created.json()["student_id"]) == (f"carol.{tag}@uni.edu", f"s{tag}")
        assert name in [u["name"] for u in instructor.get("/api/users").json()]
        duplicate = instructor.post("/api/users", json={"name": name})
        same_id = instructor.post("/api/users", json={"name": unique("carl"), "student_id": f"s{tag}"})
        invalid = instructor.post("/api/users", json={"name": "=HYPERLINK(\"http://x\")"})
    assert duplicate.status_code == 409
    assert duplicate.json() == {"detail": f"user name {name!r} is already taken"}
    assert same_id.status_code == 409 and same_id.json() == {"detail": f"the student id 's{tag}' is already {name!r}'s"}
    assert invalid.status_code == 422
    assert invalid.json() == {"detail": "the name '=HYPERLINK(\"http://x\")' holds '=': names are letters, digits, "
                                        "spaces, apostrophes, hyphens and . , _ @ +"}
    with app_league.client(created.json()["token"]) as student:
        assert student.get("/api/users/me").json()["name"] == name


# --------------------------------------------------------------------------- rosters


def post_roster(client, data: str | bytes, filename: str = "roster.csv"):
    data = data.encode() if isinstance(data, str) else data
    return client.post("/api/users/roster", files={"file": (filename, data, "text/csv")})


def people(users: list[dict]) -> list[tuple]:
    return [(user["name"], user["email"], user["student_id"]) for user in users]


def lines(report: list[dict]) -> list[tuple]:
    return [(line["line"], line["name"], line["reason"]) for line in report]


# (file as the spreadsheet saves it, how it is read, the students it makes); {t} is a tag that
# keeps names, emails and ids unique across the tests that share one league.
SPREADSHEETS = {
    "comma, first and last name": (
        "first,last,email\nAda,Lovelace {t},ada.{t}@uni.edu\nNiaj,O'Brien {t},niaj.{t}@uni.edu\n",
        ("comma", {"first": "first", "last": "last", "email": "email"}),
        [("Ada Lovelace {t}", "ada.{t}@uni.edu", None), ("Niaj O'Brien {t}", "niaj.{t}@uni.edu", None)]),
    "Excel in Europe: semicolons, BOM, CRLF": (
        "\ufeffName;E-Mail;Matrikelnummer\r\nZoë Müller {t};zoe.{t}@uni.de;M{t}1\r\n"
        "Łukasz Wiśniewski {t};lukasz.{t}@uni.pl;M{t}2\r\n",
        ("semicolon", {"name": "Name", "email": "E-Mail", "student_id": "Matrikelnummer"}),
        [("Zoë Müller {t}", "zoe.{t}@uni.de", "M{t}1"), ("Łukasz Wiśniewski {t}", "lukasz.{t}@uni.pl", "M{t}2")]),
    "tab, given name and surname": (
        "Given Name\tSurname\tStudent ID\n  Grace \t Hopper  {t}\t{t}3\n",
        ("tab", {"first": "Given Name", "last": "Surname", "student_id": "Student ID"}),
        [("Grace Hopper {t}", None, "{t}3")]),
    "quoted names holding commas": (
        'Full name,Email address\n"Lovelace, Ada {t}",lovelace.{t}@uni.edu\n"King, Jr., Martin {t}",mlk.{t}@uni.edu\n',
        ("comma", {"full": "Full name", "email": "Email address"}),
        [("Lovelace, Ada {t}", "lovelace.{t}@uni.edu", None), ("King, Jr., Martin {t}", "mlk.{t}@uni.edu", None)]),
    "Moodle's export": (
        "firstname,lastname,email,idnumber\nJosé,García López {t},jose.{t}@uni.es,{t}4\n",
        ("comma", {"first": "firstname", "last": "lastname", "email": "email", "student_id": "idnumber"}),
        [("José García López {t}", "jose.{t}@uni.es", "{t}4")]),
    "German forms: Name is the surname beside Vorname": (
        "Name;Vorname;E-Mail-Adresse\nSchmidt {t};Jürgen;j.{t}@uni.de\n",
        ("semicolon", {"name": "Name", "first": "Vorname", "email": "E-Mail-Adresse"}),
        [("Jürgen Schmidt {t}", "j.{t}@uni.de", None)]),
    "no header, one name a line": (
        "Niaj O’Brien {t}\n\n李小龙 {t}\n'T Hooft {t}\n",
        ("comma", {}),
        [("Niaj O’Brien {t}", None, None), ("李小龙 {t}", None, None), ("'T Hooft {t}", None, None)]),
}


@pytest.mark.parametrize("shape", SPREADSHEETS)
def test_roster_reads_spreadsheets_as_they_export_them(app_league, shape):
    tag = uuid.uuid4().hex[:8]
    text, (delimiter, columns), expected = SPREADSHEETS[shape]
    expected = [tuple(value and value.format(t=tag) for value in person) for person in expected]
    with app_league.client(app_league.instructor_token) as instructor:
        response = post_roster(instructor, text.format(t=tag))
    assert response.status_code == 201, response.text
    report = response.json()
    assert report["format"] == {"delimiter": delimiter, "columns": columns, "layout": "plain"}
    assert (people(report["created"]), report["skipped"], report["errors"]) == (expected, [], [])


def test_roster_of_excel_unicode_text_and_decomposed_accents(app_league):
    """Excel's "Unicode Text" (UTF-16 with a BOM, tab-separated); a Mac's decomposed "Zoë" is stored
    composed, so that it matches the same name typed elsewhere."""
    tag = uuid.uuid4().hex[:8]
    text = f"Name\tEmail\r\nZoe\u0308 {tag}\tzoe.{tag}@uni.fr\r\n"
    with app_league.client(app_league.instructor_token) as instructor:
        report = post_roster(instructor, text.encode("utf-16"), "roster.txt").json()
        again = post_roster(instructor, f"name\nZo\u00eb {tag}\n").json()
    assert people(report["created"]) == [(f"Zo\u00eb {tag}", f"zoe.{tag}@uni.fr", None)]
    assert report["format"] == {"delimiter": "tab", "columns": {"name": "Name", "email": "Email"}, "layout": "plain"}
    assert again["created"] == []
    assert lines(again["skipped"]) == [(2, f"Zo\u00eb {tag}", "already a student (same name)")]


def test_roster_creates_the_good_lines_and_lists_every_bad_one(app_league):
    tag = uuid.uuid4().hex[:8]
    roster = (f"name,email,student id\n"
              f"Ada {tag},ada.{tag}@uni.edu,{tag}1\n"  # 2
              f"=SUM(A1:A3),,\n"  # 3: a formula
              f"Eve\u202e{tag},eve.{tag}@uni.edu,\n"  # 4: a right-to-left override hiding the name's end
              f"Bob {tag},bob at uni,{tag}2\n"  # 5
              f"Cy {tag},cy.{tag}@uni.edu,1.23457E+11\n"  # 6: Excel took the id for a number
              f"Dee {tag},dee.{tag}@uni.edu,{tag}3,oops\n"  # 7
              f",nobody.{tag}@uni.edu,\n"  # 8
              f"{'x' * 101},,\n"  # 9
              f"#N/A,,\n"  # 10
              f'"Fay\n{tag}",fay.{tag}@uni.edu,{tag}4\n'  # 11-12: a quoted cell over two lines
              f"Gus {tag},gus.{tag}@uni.edu,{tag}5\n")  # 13
    with app_league.client(app_league.instructor_token) as instructor:
        response = post_roster(instructor, roster)
        listed = {user["name"] for user in instructor.get("/api/users").json()}
    assert response.status_code == 201
    report = response.json()
    assert people(report["created"]) == [(f"Ada {tag}", f"ada.{tag}@uni.edu", f"{tag}1"),
                                         (f"Fay {tag}", f"fay.{tag}@uni.edu", f"{tag}4"),
                                         (f"Gus {tag}", f"gus.{tag}@uni.edu", f"{tag}5")]
    assert {f"Ada {tag}", f"Fay {tag}", f"Gus {tag}"} <= listed
    rule = "names are letters, digits, spaces, apostrophes, hyphens and . , _ @ +"
    assert lines(report["errors"]) == [
        (3, "=SUM(A1:A3)", f"the name '=SUM(A1:A3)' holds '=': {rule}"),
        (4, f"Eve\u202e{tag}", f"the name 'Eve\\u202e{tag}' holds U+202E RIGHT-TO-LEFT OVERRIDE: {rule}"),
        (5, f"Bob {tag}", "the email 'bob at uni' is not an address: An email address must have an @-sign."),
        (6, f"Cy {tag}", "the student id '1.23457E+11' holds '+': student ids are letters, digits and - . _ / "
                         "(format the column as text in the spreadsheet so that it keeps every digit)"),
        (7, f"Dee {tag}", "4 cells where the header has 3: put cells that hold a comma in double quotes"),
        (8, None, "the name is empty"),
        (9, "x" * 100, "the name 'xxxxxxxxxxxxxxxxxxxx…' is too long: 101 characters, 100 at most"),
        (10, "#N/A", f"the name '#N/A' holds '#': {rule}"),
    ]
    assert report["skipped"] == []


def test_roster_names_duplicates_in_the_file_and_against_enrolled_students(app_league):
    tag = uuid.uuid4().hex[:8]
    colleague, _ = app_league.user("colleague", role="instructor")
    with app_league.client(app_league.instructor_token) as instructor:
        first = post_roster(instructor, f"name\nAda {tag}\nBea {tag}\n").json()  # enrolled before ids were known
        second = post_roster(instructor, (
            f"Name,Email,Student ID\n"
            f"Ada {tag},ada.{tag}@uni.edu,{tag}1\n"  # 2: enrolled by name: her email and id recorded
            f"Cal {tag},cal.{tag}@uni.edu,{tag}2\n"  # 3: new
            f"Calvin {tag},CAL.{tag}@uni.edu,\n"  # 4: line 3 again (by email, another spelling)
            f"Ada Lovelace {tag},,{tag}1\n"  # 5: Ada again (by the id line 2 recorded)
            f"Bea {tag},other.{tag}@uni.edu,{tag}3\n"  # 6: Bea by name (she had no email): recorded
            f"Bea {tag},bea2.{tag}@uni.edu,{tag}9\n"  # 7: Bea's name, another person's email and id
            f"{colleague.name},col.{tag}@uni.edu,\n"  # 8: an instructor's name
            f"Dan {tag},cal.{tag}@uni.edu,{tag}1\n"  # 9: Cal's email but Ada's id
        )).json()
        users = {user["name"]: user for user in instructor.get("/api/users").json()}
    assert people(first["created"]) == [(f"Ada {tag}", None, None), (f"Bea {tag}", None, None)]
    assert people(second["created"]) == [(f"Cal {tag}", f"cal.{tag}@uni.edu", f"{tag}2")]
    assert lines(second["skipped"]) == [
        (2, f"Ada {tag}", "already a student (same name); their email and student id recorded"),
        (4, f"Calvin {tag}", "the same student as line 3 (same email)"),
        (5, f"Ada Lovelace {tag}", f"already a student as 'Ada {tag}' (same student id)"),
        (6, f"Bea {tag}", "already a student (same name); their email and student id recorded"),
    ]
    assert lines(second["errors"]) == [
        (7, f"Bea {tag}", f"'Bea {tag}' has the same name but the email 'other.{tag}@uni.edu', not "
                          f"'bea2.{tag}@uni.edu'; if they are two people, give them distinct names "
                          "(e.g. with a middle initial)"),
        (8, colleague.name, f"the name {colleague.name!r} is another account's: give this student a name of their own "
                            "(e.g. with a middle initial)"),
        (9, f"Dan {tag}", f"its student id is that of 'Ada {tag}' but its email is that of line 3 (Cal {tag})"),
    ]
    assert (users[f"Ada {tag}"]["email"], users[f"Ada {tag}"]["student_id"]) == (f"ada.{tag}@uni.edu", f"{tag}1")
    assert (users[f"Bea {tag}"]["email"], users[f"Bea {tag}"]["student_id"]) == (f"other.{tag}@uni.edu", f"{tag}3")


@pytest.mark.parametrize("data, detail", [
    (b"PK\x03\x04\x14\x00\x06\x00", "this is a spreadsheet workbook (.xlsx or .ods), not a CSV file: save it as "
                                     "CSV UTF-8 (Excel: File > Save As > CSV UTF-8) and upload that"),
    ("name\nAda\nZo\u00eb\n".encode("cp1252"), "the roster is not UTF-8 text (line 3): save it as CSV UTF-8 "
                                                "(Excel: File > Save As > CSV UTF-8)"),
    (b"email,student id\nada@uni.edu,1\n", "line 1: no name column in 'email', 'student id': name the columns in "
                                            "the first line, e.g. name,email,student id (or first name,last name,...), "
                                            "or give one name a line without a header"),
    (b"\n\nAda;ada@uni.edu\n", "line 3: no column name recognised in 'Ada', 'ada@uni.edu': name the columns in "
                                "the first line, e.g. name,email,student id (or first name,last name,...), or give "
                                "one name a line without a header"),
    (b" \r\n", "the roster holds no names"),
    (b"name\n" + b"Ada\n" * 10_000, "the roster has more than 10000 lines: split it into several files"),
], ids=["xlsx", "cp1252", "no name column", "unknown header", "empty", "too many lines"])
def test_roster_that_cannot_be_read_is_refused_with_what_to_do(app_league, data, detail):
    with app_league.client(app_league.instructor_token) as instructor:
        response = post_roster(instructor, data)
    assert (response.status_code, response.json()) == (422, {"detail": detail})


def test_roster_late_enrolment_creates_only_the_new_students(app_league):
    names = [unique("dora"), unique("eve")]
    roster = ("name,email\n" + "".join(f"{n},{n}@school.example\n" for n in names)).encode()
    with app_league.client(app_league.instructor_token) as instructor:
        created = post_roster(instructor, roster)
        assert created.status_code == 201
        assert [u["name"] for u in created.json()["created"]] == names and created.json()["skipped"] == []
        assert all(u["token"].startswith("lg_") for u in created.json()["created"])
        with app_league.client(created.json()["created"][0]["token"]) as student:
            assert student.get("/api/users/me").json()["email"] == f"{names[0]}@school.example"

        # a late enrolment: the whole roster again, one name more (and one student revoked meanwhile)
        instructor.post(f"/api/users/{created.json()['created'][1]['id']}/revoke")
        late = unique("frank")
        added = post_roster(instructor, "name\n" + names[0] + "\n" + late + "\n" + names[1] + "\n")
        listed = [u["name"] for u in instructor.get("/api/users").json()]
    assert added.status_code == 201
    assert [u["name"] for u in added.json()["created"]] == [late]
    assert lines(added.json()["skipped"]) == [(2, names[0], "already a student (same name)"),
                                             (4, names[1], "already a student (same name); their account is "
                                                           "revoked (a new token restores it)")]
    assert listed.count(names[0]) == 1 and late in listed


def test_me_tells_a_student_their_uploads_left(app_league, models):
    user, student = app_league.student("me")
    with student:
        fresh = student.get("/api/users/me").json()["upload_quota"]
        app_league.submission(user, status=REJECTED)  # free
        app_league.submission(user)
        used = student.get("/api/users/me").json()["upload_quota"]
        for _ in range(3):
            app_league.submission(user)
        spent = student.get("/api/users/me").json()["upload_quota"]
        refused = upload(student, models["heuristic_onnx"])
    assert fresh == {"limit": 4, "used": 0, "remaining": 4, "next_free_at": None}  # LEAGUE_QUOTA_PER_DAY=4
    assert used == {"limit": 4, "used": 1, "remaining": 3, "next_free_at": None}
    assert (spent["used"], spent["remaining"]) == (4, 0)
    assert refused.status_code == 429 and spent["next_free_at"][:19] in refused.json()["detail"]
    with app_league.client(app_league.instructor_token) as instructor:
        assert instructor.get("/api/users/me").json()["upload_quota"] is None  # no quota


def test_revoked_student_is_locked_out_and_a_new_token_restores_them(app_league):
    name = unique("gus")
    with app_league.client(app_league.instructor_token) as instructor:
        created = instructor.post("/api/users", json={"name": name}).json()
        revoked = instructor.post(f"/api/users/{created['id']}/revoke")
        assert revoked.status_code == 200 and revoked.json()["active"] is False
        with app_league.client(created["token"]) as student:
            response = student.get("/api/users/me")
            assert response.status_code == 401
            assert response.json() == {"detail": "this account was revoked"}
        renewed = instructor.post(f"/api/users/{created['id']}/token").json()
    with app_league.client(renewed["token"]) as student:
        assert student.get("/api/users/me").json()["active"] is True
    with app_league.client(created["token"]) as old:
        replaced = old.get("/api/users/me")
    assert replaced.status_code == 401 and replaced.json() == {  # it says why, and whom to ask
        "detail": "unknown token (replaced by a new one, or mistyped): ask your instructor for your current token"}


def test_student_calling_instructor_endpoints_is_forbidden(app_league):
    student = create_student(app_league, unique("mallory"))
    forbidden = [
        student.get("/api/users"),
        student.post("/api/users", json={"name": unique("sneaky")}),
        student.post("/api/users/1/revoke"),
        student.put("/api/settings/evaluation", json={"seed": 1, "episodes": 1, "env_options": {}}),
        student.post("/api/evaluations/rerun", json={"all": True}),
        student.get("/api/jobs"),
    ]
    for response in forbidden:
        assert response.status_code == 403, response.request.url
        assert response.json() == {"detail": "only instructors may do this"}


def test_instructors_manage_students_only(app_league):
    """Another instructor's account is theirs: no new token for it, no revoking it."""
    colleague, _ = app_league.user("colleague", role="instructor")
    with app_league.client(app_league.instructor_token) as instructor:
        responses = [instructor.post(f"/api/users/{colleague.id}/token"),
                     instructor.post(f"/api/users/{colleague.id}/revoke")]
    assert [r.status_code for r in responses] == [404, 404]
    assert responses[0].json() == {"detail": "no such student in your course"}
