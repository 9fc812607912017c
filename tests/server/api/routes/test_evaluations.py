"""Evaluation settings and re-runs in process: the refusals, and a settings change on the boards and
in the grades. Re-evaluations a worker runs: tests/system/api/test_evaluations.py."""
from __future__ import annotations

import csv
import io
import uuid

import pytest
from sqlalchemy import select

from league.server.course.results import SUPERSEDED
from league.server.db import crud
from league.server.db.models import BASELINE, EVALUATE, LOW, QUEUED, REJECTED, STUDENT, Job
from league.server.jobs.leases import fairest_queued
from league.validation.report import ValidationReport

from ..in_process import evaluation_outcome, in_process_league


@pytest.mark.parametrize("options, message", [
    ({"observation": "lidar"}, "observation is not an evaluation setting: it follows each agent's input size"),
    ({"warp_drive": True},
     "invalid env_options: RaceOptions() got an unexpected keyword argument 'warp_drive'; valid options: "),
    ({"track_width": 5.0}, "invalid env_options: track_width must be in (0, "),
])
def test_invalid_env_options_are_refused(app_league, options, message):
    with app_league.client(app_league.instructor_token) as instructor:
        response = instructor.put("/api/settings/evaluation", json={"seed": 1, "episodes": 3, "env_options": options})
    assert response.status_code == 422
    assert response.json()["detail"].startswith(message)


def test_rerun_of_a_rejected_submission_is_a_conflict(app_league):
    user, _ = app_league.student("jay")
    rejected = app_league.submission(user, status=REJECTED).id
    with app_league.client(app_league.instructor_token) as instructor:
        response = instructor.post("/api/evaluations/rerun", json={"submission_id": rejected})
        assert response.status_code == 409
        assert response.json() == {"detail": f"submission {rejected} is rejected: only ready submissions are evaluated"}
        assert instructor.post("/api/evaluations/rerun", json={}).status_code == 422


# --------------------------------------------------------------------------- a settings change never mixes results


def board_and_grades(league, instructor) -> tuple[list[dict], list[dict]]:
    with league.client(league.instructor_token) as member:  # names: a visitor sees display names
        board = member.get("/api/leaderboard", params={"size": 100}).json()["items"]
    response = instructor.get("/api/leaderboard.csv")
    assert response.status_code == 200, response.text
    return board, list(csv.DictReader(io.StringIO(response.text)))


def validated(league, owner) -> int:
    """A new upload of `owner`, through its validation job (which queues its evaluation): its id."""
    with league.sessions.begin() as session:
        submission, validation = crud.create_submission(
            session, owner=session.get(type(owner), owner.id), name=f"{owner.name}-agent", filename="a.onnx",
            kind="onnx", sha256=uuid.uuid4().hex.ljust(64, "0"), size=1, max_attempts=1)
        submission_id, validation_id = submission.id, validation.id
    assert fairest_queued(league.sessions, limit=1) == [validation_id]  # before any re-evaluation
    league.finish_job(validation_id, ValidationReport(True, 5, None, "validated in a test"))
    return submission_id


def queued_evaluation_jobs(league) -> dict[int, Job]:
    """Queued evaluation jobs by submission id."""
    with league.sessions() as session:
        return {job.submission_id: job for job in session.scalars(
            select(Job).where(Job.kind == EVALUATE, Job.status == QUEUED).order_by(Job.id))}


@pytest.mark.parametrize("kind", ["sqlite", "postgres"])
def test_a_settings_change_never_mixes_results_on_the_board_or_in_the_grades(kind, tmp_path):
    """After a change the old results are stale, apart and unranked, at once (a long cache period);
    the re-evaluations wait at low priority behind a student's new upload; as they finish the board
    ranks them; the same settings again, or the old ones back, queue nothing for what has results."""
    old = {"seed": 11, "episodes": 3, "env_options": {}}  # backends.TEST_SETTINGS
    new = {"seed": 9, "episodes": 7, "env_options": {"obstacles": False}}
    with in_process_league(kind, tmp_path, bootstrap=False, public_cache_s=60, public_cache_max_age_s=60) as league:
        with league.sessions.begin() as session:
            course = crud.first_course(session)
            baselines, _ = crud.create_user(session, name="baselines", role=BASELINE, course=None, with_token=False)
            students = [crud.create_user(session, name=name, role=STUDENT, course=course)[0]
                        for name in ("ann", "bob", "cy")]
        owners = [baselines, *students]
        agents = [validated(league, owner) for owner in owners]
        for k, submission_id in enumerate(agents):  # evaluated with the old settings: the baseline 0/3, ..., cy 3/3
            league.finish_job(queued_evaluation_jobs(league)[submission_id].id, evaluation_outcome(k, settings=old))
        with league.client(league.instructor_token) as instructor:
            board, grades = board_and_grades(league, instructor)
            assert [(r["rank"], r["owner"], r["stale"]) for r in board] == \
                [(1, "cy", False), (2, "bob", False), (3, "ann", False), (4, "baselines", False)]

            changed = instructor.put("/api/settings/evaluation", json=new)
            assert changed.status_code == 200, changed.text
            assert changed.json() == {**new, "reevaluating": sorted(agents)}
            board, grades = board_and_grades(league, instructor)
            assert [(r["rank"], r["owner"], r["stale"], r["episodes"]) for r in board] == [  # by name, unranked
                (None, "ann", True, 3), (None, "baselines", True, 3), (None, "bob", True, 3), (None, "cy", True, 3)]
            assert [(g["student"], g["agent"] != "", g["stale"], g["rank"], g["completed"], g["mean_return"])
                    for g in grades] == [(name, True, "yes", "", "", "") for name in ("ann", "bob", "cy")]
            reevaluations = queued_evaluation_jobs(league)
            assert sorted(reevaluations) == sorted(agents) and {j.priority for j in reevaluations.values()} == {LOW}
            with league.sessions() as session:
                assert crud.jobs_in_flight(session, owner_id=students[0].id) == 0  # no upload refused for them

            # a student's new upload is validated and evaluated before any re-evaluation
            late = validated(league, students[0])
            assert fairest_queued(league.sessions, limit=1) == [queued_evaluation_jobs(league)[late].id]
            league.finish_job(queued_evaluation_jobs(league)[late].id,
                              evaluation_outcome(7, episodes=7, settings=new))
            board, _ = board_and_grades(league, instructor)
            assert [(r["rank"], r["owner"], r["submission_id"], r["stale"], r["episodes"]) for r in board] == [
                (1, "ann", late, False, 7),  # ann's new agent, on the new tracks; her old one's result is not shown
                (None, "baselines", agents[0], True, 3), (None, "bob", agents[2], True, 3),
                (None, "cy", agents[3], True, 3)]

            for k, submission_id in enumerate(agents):  # the re-evaluations finish: the baseline 6/7, ..., cy 3/7
                league.finish_job(reevaluations[submission_id].id, evaluation_outcome(6 - k, episodes=7, settings=new))
            board, grades = board_and_grades(league, instructor)
            assert [(r["rank"], r["owner"], r["stale"], r["completed"], r["episodes"]) for r in board] == [
                (1, "ann", False, 7, 7), (2, "baselines", False, 6, 7), (3, "bob", False, 4, 7), (4, "cy", False, 3, 7)]
            assert [(g["rank"], g["student"], g["stale"], g["completed"]) for g in grades] == \
                [("1", "ann", "", "7"), ("2", "bob", "", "4"), ("3", "cy", "", "3")]  # ranked among students

            assert instructor.put("/api/settings/evaluation", json=new).json()["reevaluating"] == []
            back = instructor.put("/api/settings/evaluation", json=old).json()
            assert back["reevaluating"] == [late]  # evaluated with the new settings only
            assert list(queued_evaluation_jobs(league)) == [late]
            board, _ = board_and_grades(league, instructor)
            assert [(r["rank"], r["owner"], r["submission_id"], r["stale"]) for r in board] == [
                (1, "cy", agents[3], False), (2, "bob", agents[2], False), (3, "ann", agents[1], False),
                (4, "baselines", agents[0], False)]  # the old results count again, as they were


@pytest.mark.parametrize("kind", ["sqlite", "postgres"])
def test_queued_evaluations_take_the_new_settings_or_are_superseded(kind, tmp_path):
    """An upload whose evaluation waits keeps its place and takes the new settings; a re-evaluation
    still queued when the old settings come back is superseded: its result of them counts again."""
    old = {"seed": 11, "episodes": 3, "env_options": {}}  # backends.TEST_SETTINGS
    new = {"seed": 4, "episodes": 5, "env_options": {}}
    with in_process_league(kind, tmp_path, bootstrap=False) as league:
        with league.sessions.begin() as session:
            course = crud.first_course(session)
            done, waiting = (crud.create_user(session, name=name, role=STUDENT, course=course)[0]
                             for name in ("dee", "eve"))
        evaluated = validated(league, done)
        first = queued_evaluation_jobs(league)[evaluated]
        league.finish_job(first.id, evaluation_outcome(2, settings=old))
        uploaded = validated(league, waiting)
        upload_job = queued_evaluation_jobs(league)[uploaded].id
        with league.client(league.instructor_token) as instructor:
            assert instructor.put("/api/settings/evaluation", json=new).json()["reevaluating"] == \
                sorted([evaluated, uploaded])
            jobs = queued_evaluation_jobs(league)
            assert (jobs[uploaded].id, jobs[uploaded].priority, jobs[evaluated].priority) == (upload_job, 0, LOW)
            assert instructor.get(f"/api/submissions/{uploaded}").json()["evaluation"]["settings"] == new

            assert instructor.put("/api/settings/evaluation", json=old).json()["reevaluating"] == [uploaded]
            assert list(queued_evaluation_jobs(league)) == [uploaded]  # the same job, the old settings again
            assert queued_evaluation_jobs(league)[uploaded].id == upload_job
            with league.sessions() as session:
                superseded = session.get(Job, jobs[evaluated].id)
            assert (superseded.status, superseded.error) == ("failed", SUPERSEDED)
            shown = instructor.get(f"/api/submissions/{evaluated}").json()["evaluation"]
            assert (shown["status"], shown["completed"], shown["stale"]) == ("done", 2, False)
