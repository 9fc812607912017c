"""The public course leaderboard in process: paging, the instructors' CSV, and with colliding ids and
a long cache period every change shows on the next request. The board of agents a worker evaluated,
and ratings before and after a round: tests/system/api/."""
from __future__ import annotations

import csv
import io

import pytest
from sqlalchemy import select

from league.server.db.models import INSTRUCTOR, Submission

from ....formulas import formula_cells
from ...api_calls import unique


def test_the_leaderboard_is_paginated(app_league):
    for completed in (3, 2, 1):  # at least three rows, whatever else the board holds
        app_league.submission(app_league.student("paged")[0], completed=completed)
    with app_league.student("reader")[1] as member:  # the board is the members' (the default)
        full = member.get("/api/leaderboard", params={"size": 100}).json()
        first = member.get("/api/leaderboard", params={"size": 1}).json()
        second = member.get("/api/leaderboard", params={"size": 1, "page": 2}).json()
        assert member.get("/api/leaderboard", params={"size": 101}).status_code == 422
        assert member.get("/api/leaderboard", params={"page": 0}).status_code == 422
    assert first["total"] == second["total"] == full["total"] >= 3
    assert first["items"] == full["items"][:1]
    assert second["items"] == full["items"][1:2]


def parse_csv(response) -> list[dict]:
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/csv")
    return list(csv.DictReader(io.StringIO(response.text)))


def test_instructors_export_the_leaderboard_of_their_course_as_csv(app_league):
    """One line per student of the course, ranked as on the board; students without an evaluated
    agent last; an agent name a spreadsheet would run is defused."""
    course = unique("graded course")
    _, token = app_league.user("prof", role=INSTRUCTOR, course_name=course)
    (ann, _), (bob, _), (cy, _), (dan, _) = (app_league.user(name, course_name=course)
                                             for name in ("ann", "bob", "cy", "dan"))
    app_league.submission(ann, completed=1)
    best = app_league.submission(ann, completed=3)
    bob_agent = app_league.submission(bob, completed=2)
    app_league.submission(dan, completed=3)
    with app_league.sessions.begin() as session:
        session.get(Submission, bob_agent.id).name = "=HYPERLINK(\"http://evil.example\")"
    with app_league.client(token) as instructor:
        assert instructor.post(f"/api/users/{dan.id}/revoke").status_code == 200
        rows = parse_csv(instructor.get("/api/leaderboard.csv"))
    with app_league.student("nosy")[1] as student:
        assert student.get("/api/leaderboard.csv").status_code == 403

    assert [(r["student"], r["submission_id"], r["revoked"]) for r in rows] == [
        (ann.name, str(best.id), ""), (bob.name, str(bob_agent.id), ""), (cy.name, "", ""), (dan.name, "", "yes")]
    assert rows[0]["rank"] == "1" and rows[1]["rank"] == "2" and rows[2]["rank"] == ""
    assert rows[1]["agent"] == "'=HYPERLINK(\"http://evil.example\")"
    assert (rows[0]["completed"], rows[0]["episodes"], float(rows[0]["mean_return"])) == ("3", "3", 6.0)
    assert rows[2]["completed"] == rows[2]["mean_return"] == rows[2]["rating"] == ""


def test_the_grades_are_data_in_any_spreadsheet(app_league):
    """Issue 22: an agent named to run in a spreadsheet that splits lines on ';' (Excel in much of
    Europe). Split on commas, semicolons or tabs, no cell of the grades starts a formula; the
    figures stay numbers (unquoted)."""
    course = unique("spreadsheet course")
    _, token = app_league.user("prof", role=INSTRUCTOR, course_name=course)
    ann, _ = app_league.user("ann", course_name=course)
    agent = app_league.submission(ann, completed=2)
    with app_league.sessions.begin() as session:
        session.get(Submission, agent.id).name = "fast;=2+5;=cmd|' /C calc'!A0"
    with app_league.client(token) as instructor:
        text = instructor.get("/api/leaderboard.csv").text
    assert formula_cells(text) == set()
    header, line = text.splitlines(keepends=True)
    grades = dict(zip(next(csv.reader([header])), next(csv.reader([line], quoting=csv.QUOTE_NONNUMERIC))))
    assert grades == {"rank": 1, "student": ann.name, "agent": "fast;'=2+5;'=cmd|' /C calc'!A0",
                      "submission_id": agent.id, "completed": 2, "episodes": 3, "mean_return": 4.0,
                      "mean_steps": 500.0, "mean_speed": 0.3, "rating": "", "stale": "", "revoked": ""}


# --------------------------------------------------------------------------- colliding ids, a long cache period


def heat_outcome(race: dict, order: list[int]):
    """A heat's classification in the given order of submission ids, as the race job writes it."""
    from league.evaluation import league_versions
    from league.server.jobs.race import RaceOutcome

    by_id = {entrant["submission_id"]: entrant for entrant in race["entrants"]}
    rows = [{"position": position, "car": f"car_{race['entrants'].index(by_id[i])}", **by_id[i], "outcome": "finished",
             "time": 10.0 + position, "distance": 100.0, "reason": None} for position, i in enumerate(order, start=1)]
    return RaceOutcome(rows, {"classification": rows, "versions": league_versions()}, None, "")


@pytest.mark.parametrize("kind", ["sqlite", "postgres"])
def test_colliding_ids_and_a_long_cache_period_every_change_shows_on_the_next_request(kind, tmp_path):
    """Students whose user ids equal baseline submission ids (created so on purpose) each keep a row;
    with answers kept for a minute, a finished evaluation and a finished round still show on the very
    next request, the rating column equal to the standings' as soon as the round is done."""
    from league.server.course.results import queue_evaluation
    from league.server.db import crud
    from league.server.db.models import BASELINE, READY, STUDENT, Job

    from ..in_process import evaluation_outcome, in_process_league

    with in_process_league(kind, tmp_path, bootstrap=False, public_cache_s=60, public_cache_max_age_s=60,
                           board_visibility="public") as league:  # visitors' answers are the ones kept
        with league.sessions.begin() as session:  # the instructor is user 1
            course = crud.first_course(session)
            baselines, _ = crud.create_user(session, name="baselines", role=BASELINE, course=None, with_token=False)
            owners = [baselines] * 4 + [crud.create_user(session, name=f"s{i}", role=STUDENT, course=course)[0]
                                        for i in range(4)]
            submissions, jobs = [], []
            for k, owner in enumerate(owners):
                submission, _ = crud.create_submission(session, owner=owner, name=f"agent{k}", filename="a.onnx",
                                                       kind="onnx", sha256=f"{k}".ljust(64, "0"), size=1,
                                                       max_attempts=1)
                submission.status, submission.public, submission.obs_dim = READY, owner is baselines, 5
                job = queue_evaluation(session, submission=submission, max_attempts=1)
                submissions.append(submission)
                jobs.append(job)
            session.flush()
            ids, job_ids = [s.id for s in submissions], [j.id for j in jobs]
            student_user_ids = {owner.id for owner in owners[4:]}
        assert len(student_user_ids & set(ids[:4])) >= 2, "the test must create colliding ids"

        with league.client() as public, league.client(league.instructor_token) as instructor:
            def board() -> list[dict]:
                response = public.get("/api/leaderboard", params={"size": 100})
                assert response.status_code == 200 and response.headers["cache-control"] == "public, no-cache"
                return response.json()["items"]

            assert board() == []
            league.finish_job(job_ids[4], evaluation_outcome(3))  # one student's evaluation is done
            assert [row["submission_id"] for row in board()] == [ids[4]]
            for k, job_id in enumerate(job_ids):
                if k != 4:
                    league.finish_job(job_id, evaluation_outcome(k % 4))
            rows = board()
            assert sorted(row["submission_id"] for row in rows) == sorted(ids)  # every baseline, every student
            students = [row["owner"] for row in rows if row["owner"] != "baselines"]  # a visitor: pseudonyms
            assert len(set(students)) == 4 and all(owner.startswith("Student ") for owner in students)

            etag = public.get("/api/leaderboard", params={"size": 100}).headers["etag"]
            again = public.get("/api/leaderboard", params={"size": 100}, headers={"If-None-Match": etag})
            assert (again.status_code, again.content, again.headers["etag"]) == (304, b"", etag)

            created = instructor.post("/api/championships", json={"name": "cup", "heat_size": 4})
            cid = created.json()["id"]
            assert instructor.post(f"/api/championships/{cid}/rounds").status_code == 202
            races = [public.get(f"/api/races/{i}").json()
                     for i in public.get(f"/api/championships/{cid}/rounds/1").json()["race_ids"]]
            assert len(races) == 2
            with league.sessions() as session:
                race_jobs = {j.race_id: j.id for j in session.query(Job).filter(Job.race_id.is_not(None))}
            for n, race in enumerate(races):
                order = sorted((e["submission_id"] for e in race["entrants"]), reverse=True)
                league.finish_job(race_jobs[race["id"]], heat_outcome(race, order))
                rows = board()
                standings = public.get(f"/api/championships/{cid}/standings").json()["items"]
                if n == 0:  # the round is not over: nothing counts yet
                    assert standings == [] and [row["rating"] for row in rows] == [None] * 8
            changed = public.get("/api/leaderboard", params={"size": 100}, headers={"If-None-Match": etag})
            assert changed.status_code == 200 and changed.headers["etag"] != etag
    ratings = {row["submission_id"]: (row["rating"], row["mu"], row["sigma"]) for row in standings}
    assert sorted(ratings) == sorted(ids)
    assert {row["submission_id"]: (row["rating"], row["mu"], row["sigma"]) for row in rows} == ratings


@pytest.mark.parametrize("kind", ["sqlite", "postgres"])
def test_uploads_and_validations_keep_the_state_stamp_an_evaluation_changes_it(kind, tmp_path):
    """In a deadline rush four in five finished jobs and submission changes are uploads and
    validations, which show nothing on the board: they must not make the next request recompute it."""
    from league.server.db import crud
    from league.server.db.models import STUDENT, Evaluation, Job
    from league.validation.report import ValidationReport

    from ..in_process import evaluation_outcome, in_process_league

    with in_process_league(kind, tmp_path, bootstrap=False, public_cache_s=60, public_cache_max_age_s=60,
                           board_visibility="public") as league:  # visitors' answers are the ones kept
        def stamp() -> tuple:
            with league.sessions() as session:
                return crud.public_state_stamp(session)

        with league.client() as public:
            empty = public.get("/api/leaderboard").headers["etag"]
            before = stamp()
            with league.sessions.begin() as session:
                student, _ = crud.create_user(session, name="s", role=STUDENT, course=crud.first_course(session))
                submission, validation = crud.create_submission(session, owner=student, name="agent", filename="a.onnx",
                                                                kind="onnx", sha256="1" * 64, size=1, max_attempts=1)
                submission_id, validation_id = submission.id, validation.id
            assert stamp() == before  # uploaded
            league.finish_job(validation_id, ValidationReport(True, 5, None, "validated in a test"))
            assert stamp() == before  # ready, its evaluation queued
            assert public.get("/api/leaderboard").headers["etag"] == empty
            with league.sessions() as session:
                evaluation_job = session.scalar(select(Job.id).join(Evaluation, Job.evaluation_id == Evaluation.id)
                                                .where(Evaluation.submission_id == submission_id))
            league.finish_job(evaluation_job, evaluation_outcome(2))
            assert stamp() != before
            assert [row["submission_id"] for row in public.get("/api/leaderboard").json()["items"]] == [submission_id]
