"""The schema: the Alembic migrations build exactly what the models describe, on both backends."""
from __future__ import annotations

import json
from datetime import datetime

import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import Connection, Engine, MetaData, inspect, text
from sqlalchemy.exc import IntegrityError

from league.server.course.results import settings_key
from league.server.db.models import Base
from league.server.db.session import alembic_config, make_engine, migrate

from .backends import BACKENDS


def alembic(engine: Engine, action: str, revision: str) -> None:
    """`alembic upgrade|downgrade REVISION` on the engine's database (migrations/env.py commits)."""
    config = alembic_config(engine.url.render_as_string(hide_password=False))
    with engine.connect() as connection:
        config.attributes["connection"] = connection
        getattr(command, action)(config, revision)


def engine_at(database_url: str, revision: str) -> Engine:
    """An engine on the database, its schema brought up to `revision` (an older release's)."""
    engine = make_engine(database_url)
    alembic(engine, "upgrade", revision)
    return engine


def two_courses(connection: Connection, now: datetime) -> None:
    """Courses 1 ("default") and 2 ("other"), as the schemas before 0010 hold them (settings per course)."""
    connection.execute(text("INSERT INTO courses (id, name, eval_seed, eval_episodes, eval_env_options, created_at, "
                            "updated_at) VALUES (:id, :name, 0, 3, '{}', :now, :now)"),
                       [{"id": 1, "name": "default", "now": now}, {"id": 2, "name": "other", "now": now}])


def course_with_an_assignment(connection: Connection, now: datetime) -> None:
    """Course 1 and its assignment 1, "hw1" (private seed 77), as the schemas since 0010 hold them."""
    connection.execute(text("INSERT INTO courses (id, name, created_at, updated_at) VALUES (1, 'c', :now, :now)"),
                       {"now": now})
    connection.execute(text(
        "INSERT INTO assignments (id, course_id, name, description, seed, episodes, env_options, private_seed, "
        "auto_publish, created_at, updated_at) VALUES (1, 1, 'hw1', '', 3, 5, '{}', 77, false, :now, :now)"),
        {"now": now})


def test_migrations_match_the_models_and_run_twice(backend):
    _, database_url = backend
    engine = make_engine(database_url)
    migrate(engine)
    migrate(engine)  # a second start finds the schema up to date
    with engine.connect() as connection:
        diff = compare_metadata(MigrationContext.configure(connection), Base.metadata)
        tables = set(inspect(connection).get_table_names())
    engine.dispose()
    assert diff == []
    assert {"courses", "users", "submissions", "evaluations", "episode_results", "jobs", "races", "race_replays",
            "championships", "championship_rounds", "alembic_version"} <= tables


def test_downgrade_to_nothing_and_back(backend):
    _, database_url = backend
    engine = make_engine(database_url)
    migrate(engine)
    alembic(engine, "downgrade", "base")
    with engine.connect() as connection:
        assert set(inspect(connection).get_table_names()) <= {"alembic_version"}
    migrate(engine)
    with engine.connect() as connection:
        assert "jobs" in inspect(connection).get_table_names()
    engine.dispose()


# --------------------------------------------------------------------------- 0007: results carry what produced them

COURSE_SETTINGS = {"seed": 11, "episodes": 3, "env_options": {}}  # backends.TEST_SETTINGS: the server's defaults
EARLIER_SETTINGS = {"seed": 5, "episodes": 7, "env_options": {"obstacles": False}}  # changed, never re-run


def fill_0006(database_url: str) -> None:
    """A league as the 0006 schema held it, written by alembic and plain SQL: a course whose
    instructor once evaluated with other settings, a baseline, three students, a queued upload and
    a finished race."""
    engine = engine_at(database_url, "0006")
    now = datetime(2026, 11, 20, 12, 0)
    with engine.begin() as connection:
        tables = MetaData()
        tables.reflect(bind=connection)

        def insert(table: str, expected_id: int | None = None, **row) -> None:
            """A row, its id drawn by the database (a fresh one: 1, 2, ... as the test expects)."""
            new_id = connection.execute(tables.tables[table].insert().values(**row)).inserted_primary_key[0]
            assert expected_id is None or new_id == expected_id

        insert("courses", 1, name="default", eval_seed=11, eval_episodes=3, eval_env_options={},
               created_at=now, updated_at=now)
        insert("users", 1, name="baselines", role="baseline", course_id=None, created_at=now)
        for user_id, name in ((2, "ann"), (3, "bob"), (4, "cy")):
            insert("users", user_id, name=name, role="student", course_id=1, token_hash=name * 16, created_at=now)
        # submission: (owner, [(evaluation settings, completed of 3 or 7, status)...])
        agents = {1: (1, [(COURSE_SETTINGS, 1, "done")]),
                  2: (2, [(COURSE_SETTINGS, 3, "done")]), 3: (2, [(COURSE_SETTINGS, 2, "done")]),
                  4: (3, [(COURSE_SETTINGS, 2, "done"), (EARLIER_SETTINGS, 7, "done"),
                          (COURSE_SETTINGS, None, "failed")]),
                  5: (4, [(EARLIER_SETTINGS, 6, "done")]),
                  6: (2, [(COURSE_SETTINGS, None, "queued")])}
        evaluation_id = 0
        for submission_id, (owner, evaluations) in agents.items():
            insert("submissions", submission_id, owner_id=owner, name=f"agent{submission_id}", filename="a.onnx",
                   kind="onnx", sha256=f"{submission_id}".ljust(64, "0"), size=1, status="ready", obs_dim=5,
                   public=owner == 1, created_at=now, updated_at=now)
            for settings, completed, status in evaluations:
                evaluation_id += 1
                episodes = settings["episodes"]
                figures = {} if completed is None else {
                    "completed": completed, "episodes_total": episodes, "mean_return": completed * 2.0,
                    "mean_steps": 500.0, "mean_speed": 0.3, "result_settings": {**settings, "agent": "a"}}
                insert("evaluations", evaluation_id, submission_id=submission_id, course_id=1, settings=settings,
                       status=status, created_at=now, finished_at=None if status == "queued" else now, **figures)
                insert("jobs", kind="evaluate", owner_id=owner, submission_id=submission_id,
                       evaluation_id=evaluation_id, status=status, attempts=int(status != "queued"), max_attempts=3,
                       created_at=now, enqueued_at=now, finished_at=None if status == "queued" else now)
        insert("races", 1, course_id=1, seed=3, env_options={}, status="done", created_at=now, finished_at=now,
               entrants=[{"submission_id": 2, "name": "agent2", "owner": "ann"}],
               classification=[{"position": 1, "car": "car_0", "submission_id": 2, "name": "agent2", "owner": "ann",
                                "outcome": "finished", "time": 20.0, "distance": 1.0, "reason": None}])
    engine.dispose()


@pytest.mark.parametrize("kind", BACKENDS)
def test_0007_keys_existing_results_so_that_the_board_keeps_what_0006_ranked(kind, tmp_path):
    """Upgraded by the server's own start: every result the 0006 board ranked with the course's
    settings keeps its rank and figures; what it mixed in from earlier settings is shown apart,
    stale; what produced each finished result is recorded; the queued upload keeps its place; and
    down to 0006 again, nothing is lost."""
    from .api.in_process import in_process_league

    with in_process_league(kind, tmp_path, prepare=fill_0006, bootstrap=False) as league:
        with league.client(league.instructor_token) as member:  # names: a visitor sees display names
            board = member.get("/api/leaderboard", params={"size": 100}).json()["items"]
            race = member.get("/api/races/1").json()
        with league.client(league.instructor_token) as instructor:
            ann_agent = instructor.get("/api/submissions/2").json()["evaluation"]
            bob_agent = instructor.get("/api/submissions/4").json()["evaluation"]
            queued = [job for job in instructor.get("/api/jobs").json() if job["status"] == "queued"]
        engine = make_engine(league.settings.database_url)  # and back to 0006, every row kept
        alembic(engine, "downgrade", "0006")
        with engine.connect() as connection:
            assert connection.execute(text("SELECT count(*) FROM evaluations")).scalar() == 8
        engine.dispose()
    # 0006 ranked: bob 7/7 (earlier settings), cy 6/7 (earlier settings), ann 3/3, the baseline 1/3
    assert [(row["rank"], row["owner"], row["submission_id"], row["completed"], row["episodes"], row["stale"])
            for row in board] == [(1, "ann", 2, 3, 3, False), (2, "bob", 4, 2, 3, False),
                                  (3, "baselines", 1, 1, 3, False), (None, "cy", 5, 6, 7, True)]
    versions = {"physics": 1, "track_format": 1, "package": "0.1.0"}
    assert ann_agent["result_key"] == settings_key(COURSE_SETTINGS) and ann_agent["versions"] == versions
    assert (bob_agent["status"], bob_agent["stale"]) == ("failed", False)  # its newest of the course's settings
    assert race["versions"] == versions
    assert [(job["submission_id"], job["priority"]) for job in queued] == [(6, 0)]


# --------------------------------------------------------------------------- 0008: users gain email and student_id


def test_users_gain_email_and_student_id_with_their_data_kept(backend):
    """0008 on a database of the previous schema (0007) that holds users: every row kept, both fields
    empty; a student id is then unique within its course, and many students may have none."""
    _, database_url = backend
    engine = engine_at(database_url, "0007")
    created = datetime(2026, 11, 1)
    with engine.begin() as connection:
        two_courses(connection, created)
        connection.execute(text("INSERT INTO users (id, name, role, course_id, token_hash, created_at) "
                                "VALUES (:id, :name, :role, :course, :hash, :now)"),
                           [{"id": 1, "name": "prof", "role": "instructor", "course": 1, "hash": "a" * 64,
                             "now": created},
                            {"id": 2, "name": "Ada", "role": "student", "course": 1, "hash": "b" * 64, "now": created},
                            {"id": 3, "name": "Bea", "role": "student", "course": 2, "hash": None, "now": created}])
    migrate(engine)
    with engine.begin() as connection:
        rows = connection.execute(text("SELECT id, name, role, course_id, token_hash, email, student_id "
                                       "FROM users ORDER BY id")).all()
        connection.execute(text("UPDATE users SET student_id = 's1' WHERE id IN (2, 3)"))  # two courses: allowed
        connection.execute(text("UPDATE users SET email = 'ada@uni.edu' WHERE id = 2"))
    with pytest.raises(IntegrityError), engine.begin() as connection:
        connection.execute(text("INSERT INTO users (name, role, course_id, student_id, created_at) "
                                "VALUES ('Cal', 'student', 1, 's1', :now)"), {"now": created})
    engine.dispose()
    assert [tuple(row) for row in rows] == [(1, "prof", "instructor", 1, "a" * 64, None, None),
                                            (2, "Ada", "student", 1, "b" * 64, None, None),
                                            (3, "Bea", "student", 2, None, None, None)]


# ------------------------------------------------------------------------ 0010: a course becomes its default assignment


@pytest.mark.parametrize("kind", BACKENDS)
def test_0010_makes_each_course_one_default_assignment_and_every_answer_stays(kind, tmp_path):
    """Upgraded by the server's own start from a league of the older schema: the course's settings are its
    default assignment's (no due time, open), every submission and evaluation belongs to it, the
    assignment's public board is the leaderboard, which ranks as before; down to 0008, the course's
    settings are back."""
    from .api.in_process import in_process_league

    with in_process_league(kind, tmp_path, prepare=fill_0006, bootstrap=False) as league:
        with league.client(league.instructor_token) as instructor:  # (visitors see pseudonyms)
            board = instructor.get("/api/leaderboard", params={"size": 100}).json()["items"]
            settings = instructor.get("/api/settings/evaluation").json()
            assignments = instructor.get("/api/assignments").json()
            assignment_board = instructor.get(f"/api/assignments/{assignments[0]['id']}/board",
                                              params={"size": 100}).json()["items"]
            submissions = instructor.get("/api/submissions", params={"all": True}).json()
        engine = make_engine(league.settings.database_url)
        alembic(engine, "downgrade", "0008")
        with engine.connect() as connection:
            course = connection.execute(text("SELECT eval_seed, eval_episodes FROM courses")).one()
            assert connection.execute(text("SELECT count(*) FROM submissions")).scalar() == 6
        engine.dispose()
    assert settings == COURSE_SETTINGS
    assert [(a["name"], a["seed"], a["episodes"], a["due_at"], a["opens_at"], a["state"]) for a in assignments] == [
        ("default", 11, 3, None, None, "open")]
    assert {s["assignment_id"] for s in submissions} == {assignments[0]["id"]}
    assert [(row["rank"], row["owner"], row["submission_id"], row["stale"]) for row in board] == [
        (1, "ann", 2, False), (2, "bob", 4, False), (3, "baselines", 1, False), (None, "cy", 5, True)]
    assert assignment_board == board
    assert tuple(course) == (11, 3)
# --------------------------------------------------------------------------- 0013: submissions gain probe actions


def test_submissions_gain_probe_actions_with_their_data_kept_and_lose_them_on_downgrade(backend):
    """0013 on a database of 0008 that holds submissions: every row kept, not probed; a downgrade
    back to 0008 keeps the rows too."""
    _, database_url = backend
    engine = engine_at(database_url, "0008")
    created = datetime(2026, 11, 1)
    with engine.begin() as connection:
        connection.execute(text("INSERT INTO users (id, name, role, created_at) VALUES (1, 'Ada', 'student', :now)"),
                           {"now": created})
        connection.execute(text("INSERT INTO submissions (id, owner_id, name, filename, kind, sha256, size, status, "
                                "public, created_at, updated_at) VALUES (:id, 1, :name, 'a.onnx', 'onnx', :sha, 10, "
                                "'ready', false, :now, :now)"),
                           [{"id": i, "name": f"agent {i}", "sha": str(i) * 64, "now": created} for i in (1, 2)])
    migrate(engine)
    with engine.begin() as connection:
        rows = connection.execute(text("SELECT id, name, sha256, status, probe_key, probe_actions FROM submissions "
                                       "ORDER BY id")).all()
        connection.execute(text("UPDATE submissions SET probe_key = :key, probe_actions = :data WHERE id = 1"),
                           {"key": "f" * 16, "data": b"\0" * 512})
    alembic(engine, "downgrade", "0008")
    with engine.connect() as connection:
        kept = connection.execute(text("SELECT id, name FROM submissions ORDER BY id")).all()
        columns = {c["name"] for c in inspect(connection).get_columns("submissions")}
    engine.dispose()
    assert [tuple(row) for row in rows] == [(1, "agent 1", "1" * 64, "ready", None, None),
                                            (2, "agent 2", "2" * 64, "ready", None, None)]
    assert [tuple(row) for row in kept] == [(1, "agent 1"), (2, "agent 2")]
    assert not {"probe_key", "probe_actions"} & columns


# --------------------------------------------------------------------------- 0012: privacy of the boards


def test_existing_courses_stay_public_and_get_pseudonym_keys_users_no_display_name(backend):
    """0012 on a database of the previous schema (0013) with two courses and their users: the
    courses keep showing their boards to anyone (an upgrade changes nothing silently), each with its
    own pseudonym key; every user row kept, without a display name, which is then unique in a course."""
    _, database_url = backend
    engine = engine_at(database_url, "0013")
    created = datetime(2026, 11, 1)
    with engine.begin() as connection:
        two_courses(connection, created)
        connection.execute(text("INSERT INTO users (id, name, role, course_id, email, created_at) "
                                "VALUES (:id, :name, :role, :course, :email, :now)"),
                           [{"id": 1, "name": "prof", "role": "instructor", "course": 1, "email": None, "now": created},
                            {"id": 2, "name": "Ada", "role": "student", "course": 1, "email": "a@u.edu",
                             "now": created},
                            {"id": 3, "name": "Bea", "role": "student", "course": 2, "email": None, "now": created}])
    migrate(engine)
    with engine.begin() as connection:
        courses = connection.execute(text("SELECT id, name, board_visibility, pseudonym_key FROM courses "
                                          "ORDER BY id")).all()
        users = connection.execute(text("SELECT id, name, course_id, email, display_name FROM users ORDER BY id")).all()
        connection.execute(text("UPDATE users SET display_name = 'Zed' WHERE id IN (2, 3)"))  # two courses: allowed
    with pytest.raises(IntegrityError), engine.begin() as connection:
        connection.execute(text("UPDATE users SET display_name = 'Zed' WHERE id = 1"))
    engine.dispose()
    assert [(row[0], row[1], row[2]) for row in courses] == [(1, "default", "public"), (2, "other", "public")]
    assert all(row[3] is not None for row in courses) and courses[0][3] != courses[1][3]
    assert [tuple(row) for row in users] == [(1, "prof", 1, None, None), (2, "Ada", 1, "a@u.edu", None),
                                             (3, "Bea", 2, None, None)]


# --------------------------------------------------------------------------- 0016: assignments gain a rubric


def test_assignments_gain_a_rubric_with_their_rows_kept_and_lose_it_on_downgrade(backend):
    """0016 on a 0010 database that holds an assignment: the row kept, no rubric; a rubric (JSON)
    reads back; the downgrade drops the column and keeps the row."""
    _, database_url = backend
    engine = engine_at(database_url, "0010")
    now = datetime(2026, 11, 1)
    with engine.begin() as connection:
        course_with_an_assignment(connection, now)
    migrate(engine)
    rubric = '{"kind": "formula", "max_points": 10, "formula": "10 * completed"}'
    with engine.begin() as connection:
        assert connection.execute(text("SELECT name, private_seed, rubric FROM assignments")).one() == ("hw1", 77, None)
        connection.execute(text("UPDATE assignments SET rubric = :rubric"), {"rubric": rubric})
    with engine.connect() as connection:
        stored = connection.execute(text("SELECT rubric FROM assignments")).scalar_one()
        assert (json.loads(stored) if isinstance(stored, str) else stored)["formula"] == "10 * completed"
    alembic(engine, "downgrade", "0010")
    with engine.connect() as connection:
        assert "rubric" not in {c["name"] for c in inspect(connection).get_columns("assignments")}
        assert connection.execute(text("SELECT name, private_seed FROM assignments")).one() == ("hw1", 77)
    migrate(engine)
    engine.dispose()


# --------------------------------------------------------------------------- 0017: championships of an assignment


def test_championships_keep_their_rows_belong_to_no_assignment_and_lose_the_column_on_downgrade(backend):
    """0017 on a 0014 database that holds a championship: the row kept, of no assignment (it races the
    active submissions, as before); one can then belong to an assignment; the downgrade keeps the row."""
    _, database_url = backend
    engine = engine_at(database_url, "0014")
    now = datetime(2026, 11, 1)
    with engine.begin() as connection:
        course_with_an_assignment(connection, now)
        connection.execute(text(
            "INSERT INTO championships (id, course_id, name, env_options, heat_size, points, include_baselines, seed, "
            "created_at) VALUES (1, 1, 'cup', '{}', 4, '[3, 1]', true, 9, :now)"), {"now": now})
    migrate(engine)
    with engine.begin() as connection:
        assert connection.execute(text("SELECT name, seed, assignment_id FROM championships")).one() == ("cup", 9, None)
        connection.execute(text("UPDATE championships SET assignment_id = 1"))
    alembic(engine, "downgrade", "0014")
    with engine.connect() as connection:
        assert "assignment_id" not in {c["name"] for c in inspect(connection).get_columns("championships")}
        assert connection.execute(text("SELECT name, seed FROM championships")).one() == ("cup", 9)
    migrate(engine)
    engine.dispose()


# --------------------------------------------------------------------------- 0020: random pseudonyms


def test_existing_users_get_random_pseudonyms_distinct_in_their_course_and_lose_them_on_downgrade(backend):
    """0020 on a 0017 database with two courses: each user of a course gets a pseudonym, distinct in
    the course (the unique index refuses a second one), none for a user of no course; rows kept."""
    _, database_url = backend
    engine = engine_at(database_url, "0017")
    created = datetime(2026, 11, 1)
    people = [(1, "prof", "instructor", 1), (2, "Ada", "student", 1), (3, "Bea", "student", 1),
              (4, "Cy", "student", 2), (5, "baselines", "baseline", None)]
    with engine.begin() as connection:
        connection.execute(text("INSERT INTO courses (id, name, created_at, updated_at) "
                                "VALUES (:id, :name, :now, :now)"),
                           [{"id": 1, "name": "default", "now": created}, {"id": 2, "name": "other", "now": created}])
        connection.execute(text("INSERT INTO users (id, name, role, course_id, created_at) "
                                "VALUES (:id, :name, :role, :course, :now)"),
                           [{"id": i, "name": n, "role": r, "course": c, "now": created} for i, n, r, c in people])
    migrate(engine)
    with engine.connect() as connection:
        rows = connection.execute(text("SELECT id, name, course_id, pseudonym FROM users ORDER BY id")).all()
    numbers = {row[0]: row[3] for row in rows}
    assert [(row[0], row[1], row[2]) for row in rows] == [(i, n, c) for i, n, _, c in people]
    assert numbers[5] is None and all(1 <= numbers[i] <= 999_999 for i in (1, 2, 3, 4))
    assert len({numbers[1], numbers[2], numbers[3]}) == 3
    with pytest.raises(IntegrityError), engine.begin() as connection:
        connection.execute(text("UPDATE users SET pseudonym = :n WHERE id = 3"), {"n": numbers[2]})
    alembic(engine, "downgrade", "0017")
    with engine.connect() as connection:
        assert "pseudonym" not in {c["name"] for c in inspect(connection).get_columns("users")}
        assert connection.execute(text("SELECT count(*) FROM users")).scalar_one() == 5
    migrate(engine)
    engine.dispose()


def test_a_backup_before_an_upgrade_is_taken_without_writing_to_the_older_schemas_audit_log(backend, tmp_path,
                                                                                            monkeypatch):
    """`league backup` records itself in the audit log at this version's schema only: on a database still
    at an older release's (the backup an administrator takes before upgrading) it writes nothing there."""
    from league.server.cli import main

    _, database_url = backend
    engine = engine_at(database_url, "0008")  # before the audit log existed (0015)
    monkeypatch.setenv("LEAGUE_DATABASE_URL", database_url)
    assert main(["backup", str(tmp_path / "before-upgrade.bak"), "--data-dir", str(tmp_path / "data")]) == 0
    with engine.connect() as connection:
        assert "audit_events" not in inspect(connection).get_table_names()
    migrate(engine)
    assert main(["backup", str(tmp_path / "after.bak"), "--data-dir", str(tmp_path / "data")]) == 0
    with engine.connect() as connection:
        assert connection.execute(text("SELECT action, actor_name FROM audit_events")).all() == [
            ("league.backup", "league CLI")]
    engine.dispose()


# --------------------------------------------------------------------------- 0024: Canvas's ids of a student


def test_users_gain_canvas_ids_with_their_data_kept_and_lose_them_on_downgrade(backend):
    """0024 on a 0017 database that holds users: every row kept, no Canvas ids; they are then
    stored; the downgrade drops both columns and keeps the rows."""
    _, database_url = backend
    engine = engine_at(database_url, "0017")
    created = datetime(2026, 11, 1)
    with engine.begin() as connection:
        course_with_an_assignment(connection, created)
        connection.execute(text("INSERT INTO users (id, name, role, course_id, student_id, created_at) "
                                "VALUES (2, 'Ada', 'student', 1, 's1', :now)"), {"now": created})
    migrate(engine)
    with engine.begin() as connection:
        query = "SELECT name, student_id, canvas_id, sis_login_id FROM users"
        assert tuple(connection.execute(text(query)).one()) == ("Ada", "s1", None, None)
        connection.execute(text("UPDATE users SET canvas_id = '4011', sis_login_id = 'alovelace'"))
        assert tuple(connection.execute(text(query)).one()) == ("Ada", "s1", "4011", "alovelace")
    alembic(engine, "downgrade", "0017")
    with engine.connect() as connection:
        assert {"canvas_id", "sis_login_id"}.isdisjoint(c["name"] for c in inspect(connection).get_columns("users"))
        assert tuple(connection.execute(text("SELECT name, student_id FROM users")).one()) == ("Ada", "s1")


# --------------------------------------------------------------------------- 0018: finals' candidates


def test_finals_frozen_before_0018_stay_decided_and_published_results_are_kept_as_of_the_publication(backend):
    """0018 on a 0017 database with a published assignment whose final was frozen and evaluated: the
    final counts as decided when frozen (nothing to wait for), its evaluation is the one of the
    publication (a grade says so only if that changes); the downgrade keeps the row."""
    _, database_url = backend
    engine = engine_at(database_url, "0017")
    now, frozen = datetime(2026, 11, 1), datetime(2026, 10, 30, 23, 59)
    with engine.begin() as connection:
        course_with_an_assignment(connection, now)
        connection.execute(text("UPDATE assignments SET due_at = :frozen, published_at = :now"),
                           {"frozen": frozen, "now": now})
        connection.execute(text("INSERT INTO users (id, name, role, course_id, created_at) "
                                "VALUES (1, 'ann', 'student', 1, :now)"), {"now": now})
        connection.execute(text(
            "INSERT INTO submissions (id, owner_id, assignment_id, name, filename, kind, sha256, size, status, public, "
            "created_at, updated_at) VALUES (1, 1, 1, 'a', 'a.onnx', 'onnx', :sha, 1, 'ready', false, :now, :now)"),
            {"sha": "0" * 64, "now": now})
        connection.execute(text("INSERT INTO evaluations (id, submission_id, course_id, assignment_id, track, "
                                "settings, status, created_at) VALUES (7, 1, 1, 1, 'private', '{}', 'done', :now)"),
                           {"now": now})
        connection.execute(text("INSERT INTO student_assignments (id, assignment_id, user_id, final_at, "
                                "final_submission_id, final_evaluation_id) VALUES (1, 1, 1, :frozen, 1, 7)"),
                           {"frozen": frozen})
    migrate(engine)
    with engine.connect() as connection:
        row = connection.execute(text("SELECT final_at, final_decided_at, final_candidates, published_evaluation_id "
                                      "FROM student_assignments")).one()
        assert row[0] is not None and row[1] == row[0]  # (SQLite reads a time back as text)
        assert (row[2], row[3]) == (None, 7)
    alembic(engine, "downgrade", "0017")
    with engine.connect() as connection:
        columns = {c["name"] for c in inspect(connection).get_columns("student_assignments")}
        assert not columns & {"final_decided_at", "final_candidates", "published_evaluation_id"}
        assert connection.execute(text("SELECT final_submission_id, final_evaluation_id FROM student_assignments")
                                  ).one() == (1, 7)


# --------------------------------------------------------------------------- 0021: the automatic assignment


def test_0021_marks_each_courses_automatic_assignment_and_keeps_open_those_beside_the_instructors_own(backend):
    """0021 on a 0017 database: course 1 has its default and an assignment of its instructor's (the
    default stays open, as before the upgrade), course 2 only its default (it will close when the
    first one is made), course 3 no assignment named default first (nothing is automatic there)."""
    _, database_url = backend
    engine = engine_at(database_url, "0017")
    now = datetime(2026, 11, 1)
    with engine.begin() as connection:
        for course_id in (1, 2, 3):
            connection.execute(text("INSERT INTO courses (id, name, created_at, updated_at) "
                                    "VALUES (:id, :name, :now, :now)"), {"id": course_id, "name": f"c{course_id}",
                                                                         "now": now})
        for assignment_id, course_id, name in ((1, 1, "default"), (2, 2, "default"), (3, 1, "hw1"), (4, 3, "hw"),
                                               (5, 3, "default")):
            connection.execute(text(
                "INSERT INTO assignments (id, course_id, name, description, seed, episodes, env_options, private_seed, "
                "auto_publish, created_at, updated_at) VALUES (:id, :course, :name, '', 3, 5, '{}', 77, false, "
                ":now, :now)"), {"id": assignment_id, "course": course_id, "name": name, "now": now})
    migrate(engine)
    with engine.connect() as connection:
        rows = connection.execute(text("SELECT id, automatic, keep_open FROM assignments ORDER BY id")).all()
    assert [(i, bool(a), bool(k)) for i, a, k in rows] == [
        (1, True, True), (2, True, False), (3, False, False), (4, False, False), (5, False, False)]
    alembic(engine, "downgrade", "0017")
    with engine.connect() as connection:
        columns = {c["name"] for c in inspect(connection).get_columns("assignments")}
        assert not {"automatic", "keep_open"} & columns
        assert connection.execute(text("SELECT count(*) FROM assignments")).scalar_one() == 5
    migrate(engine)
    engine.dispose()
