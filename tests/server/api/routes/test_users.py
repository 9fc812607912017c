"""Accounts, in process on both backends: instructors create students (one or a CSV roster) and revoke them."""
from __future__ import annotations

import os
import subprocess
import sys
import uuid

from league.server.db.models import REJECTED

from ...conftest import create_student, upload


def unique(name: str) -> str:
    return f"{name}-{uuid.uuid4().hex[:6]}"


def test_cli_token_authenticates_the_instructor(app_league):
    """`league users add` writes to the same database as the app; its token is accepted."""
    env = {**os.environ, "LEAGUE_DATABASE_URL": app_league.settings.resolved_database_url,
           "LEAGUE_QUEUE_URL": app_league.settings.resolved_queue_url, "LEAGUE_DATA_DIR": str(app_league.settings.data_dir)}
    name = unique("prof")
    added = subprocess.run([sys.executable, "-m", "league.server", "users", "add", name, "--role", "instructor"],
                           env=env, capture_output=True, text=True, timeout=120)
    assert added.returncode == 0, added.stderr
    with app_league.client(added.stdout.strip()) as instructor:
        me = instructor.get("/api/users/me")
    assert me.status_code == 200
    assert (me.json()["name"], me.json()["role"], me.json()["active"]) == (name, "instructor", True)


def test_instructor_creates_a_student_whose_token_works(app_league):
    name = unique("carol")
    with app_league.client(app_league.instructor_token) as instructor:
        created = instructor.post("/api/users", json={"name": name})
        assert created.status_code == 201
        assert created.json()["token"].startswith("lg_") and created.json()["role"] == "student"
        assert name in [u["name"] for u in instructor.get("/api/users").json()]
        duplicate = instructor.post("/api/users", json={"name": name})
    assert duplicate.status_code == 409
    assert duplicate.json() == {"detail": f"user name {name!r} is already taken"}
    with app_league.client(created.json()["token"]) as student:
        assert student.get("/api/users/me").json()["name"] == name


def test_roster_creates_the_new_students_and_skips_existing_names(app_league):
    names = [unique("dora"), unique("eve")]
    roster = ("name,email\n" + "".join(f"{n},{n}@school.example\n" for n in names)).encode()
    with app_league.client(app_league.instructor_token) as instructor:
        created = instructor.post("/api/users/roster", files={"file": ("roster.csv", roster, "text/csv")})
        assert created.status_code == 201
        assert [u["name"] for u in created.json()["created"]] == names and created.json()["skipped"] == []
        assert all(u["token"].startswith("lg_") for u in created.json()["created"])

        # a late enrolment: the whole roster again, one name more
        late = unique("frank")
        again = ("name\n" + names[0] + "\n" + late + "\n" + names[1] + "\n").encode()
        added = instructor.post("/api/users/roster", files={"file": ("roster.csv", again, "text/csv")})
        assert added.status_code == 201
        assert [u["name"] for u in added.json()["created"]] == [late]
        assert added.json()["skipped"] == [names[0], names[1]]

        # an invalid name: nobody is created
        bad = ("name\n" + unique("gina") + "\n" + "bad/name" + "\n").encode()
        refused = instructor.post("/api/users/roster", files={"file": ("roster.csv", bad, "text/csv")})
        assert refused.status_code == 409
        assert refused.json()["detail"] == ("no student was created: invalid user name 'bad/name': "
                                            "1-100 letters, digits, spaces or . @ + - _")
        listed = [u["name"] for u in instructor.get("/api/users").json()]
    assert listed.count(names[0]) == 1 and late in listed
    assert not any(name.startswith("gina-") for name in listed)


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
