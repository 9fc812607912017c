"""Several courses on one server: an instructor and a student of course 2 walk every route of the
API's schema (every method) against a league where course 1 has an unpublished assignment whose
private test is done (a student's final and a baseline) and another final's is still queued. No
answer holds course 1's private seed, private episode seeds or private figures; every action on
course 1's objects (cancel, re-run, edit, extend, publish, delete, revoke, race...) is refused (403
or 404); and afterwards nothing of course 1 changed. Each course's baseline results, jobs and
episodes are its own; display names are unique within a course only.

In process, on both backends (tests/server/api/in_process.py), as the students' leak walk of
test_assignments.py.
"""
from __future__ import annotations

import itertools
import re
import uuid
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone

import pytest
from sqlalchemy import select

from league.evaluation import episode_seeds, league_versions
from league.server.app import catch_up
from league.server.course.assignments import private_visible
from league.server.course.courses import add_course
from league.server.db import crud
from league.server.db.models import (
    BASELINE, DONE, INSTRUCTOR, PRIVATE_TRACKS, READY, Assignment, AuditEvent, Championship, Course, Evaluation, Job,
    Race, StudentAssignment, Submission, User,
)
from league.server.course.results import settings_key
from league.server.jobs.evaluate import EvaluationOutcome

from ...api_calls import unique
from ...backends import BACKENDS
from ..in_process import every_get, evaluation_outcome, in_process_league

DUE = datetime(2030, 3, 8, 23, 59, tzinfo=timezone.utc)
EPISODES = 4
STUDENT_FIGURE, BASELINE_FIGURE = 777.125, 555.375  # the private tests' mean returns: secret until published
RUBRIC = {"kind": "points", "max_points": 10, "completed": {"kind": "linear", "points": 10}}


@pytest.fixture(scope="module", params=BACKENDS)
def league(request, tmp_path_factory):
    """A league of its own: the test moves its clock past a due time."""
    with in_process_league(request.param, tmp_path_factory.mktemp(f"courses-{request.param}"),
                           quota_per_day=1000) as league_:
        yield league_
        league_.app.state.services.clock.set(None)


def ready(league, owner: User, assignment_id: int) -> int:
    """A ready submission of the assignment with a finished public evaluation."""
    with league.sessions.begin() as session:
        assignment = session.get(Assignment, assignment_id)
        submission, _ = crud.create_submission(session, owner=session.get(User, owner.id), assignment=assignment,
                                               name=unique("agent"), filename="a.onnx", kind="onnx",
                                               sha256=uuid.uuid4().hex.ljust(64, "0"), size=1, max_attempts=1)
        submission.status, submission.obs_dim = READY, 5
        settings = assignment.evaluation_settings()
        evaluation, _ = crud.create_evaluation(session, submission=submission, assignment=assignment,
                                               settings=settings, result_key=settings_key(settings), max_attempts=1)
        evaluation.status, evaluation.completed, evaluation.episodes_total = DONE, 2, EPISODES
        evaluation.mean_return, evaluation.mean_steps, evaluation.mean_speed = 4.0, 500.0, 0.3
        session.flush()
        return submission.id


def private_outcome(private_seed: int, mean_return: float) -> EvaluationOutcome:
    """What a private evaluation job returns: the private tracks' real episode seeds, made-up figures."""
    settings = {"seed": private_seed, "episodes": EPISODES, "env_options": {}}
    rows = [{"seed": seed, "steps": 100, "return": mean_return, "mean_speed": 0.3, "outcome": "finished",
             "reason": None} for seed in episode_seeds(private_seed, EPISODES)]
    record = {**settings, "versions": league_versions(), "result_key": settings_key(settings)}
    return EvaluationOutcome({"episodes": rows, "completed": EPISODES, "episodes_total": EPISODES,
                              "mean_return": mean_return, "mean_steps": 100.0, "mean_speed": 0.3,
                              "settings": record}, None, "a private run")


@dataclass
class TwoCourses:
    course1: int
    course2: int
    hw: dict  # course 1's assignment, due and unpublished, its private test done
    private_seed: int
    secrets: list[str]
    instructor2: str  # tokens
    student2: str
    baseline: int  # the bundled agent's submission id
    submissions: list[int]  # course 1's students'
    students: list[User]
    race_ids: list[int]
    championship: int
    course2_jobs: list[int]  # course 2's evaluations of the baselines (queued by add_course)
    ids: dict = field(default_factory=dict)


def private_evaluations(league, assignment_id: int, owner_role: str | None = None) -> dict[int, tuple[int, int]]:
    """The assignment's private evaluations: submission id -> (evaluation id, job id)."""
    with league.sessions() as session:
        query = (select(Evaluation.submission_id, Evaluation.id, Job.id).join(Job, Job.evaluation_id == Evaluation.id)
                 .join(Submission, Submission.id == Evaluation.submission_id)
                 .join(User, User.id == Submission.owner_id)
                 .where(Evaluation.assignment_id == assignment_id, Evaluation.track == PRIVATE_TRACKS))
        if owner_role is not None:
            query = query.where(User.role == owner_role)
        return {submission: (evaluation, job) for submission, evaluation, job in session.execute(query)}


def two_courses(league) -> TwoCourses:
    with league.sessions.begin() as session:  # validated, as the bundled agents are once a worker runs
        baseline = session.scalar(select(Submission.id).join(User, User.id == Submission.owner_id)
                                  .where(User.role == BASELINE))
        row = session.get(Submission, baseline)
        row.status, row.obs_dim = READY, 5
        course1 = crud.first_course(session).id
        course2, queued = add_course(session, name=unique("course"), settings=league.settings)
        course2, course2_jobs = course2.id, [job.id for job in queued]
        _, instructor2 = crud.create_user(session, name=unique("prof2"), role=INSTRUCTOR,
                                          course=session.get(Course, course2))
        _, student2 = crud.create_user(session, name=unique("kid2"), role="student",
                                       course=session.get(Course, course2))
    assert course2_jobs, "a new course queues the baselines' evaluations on its default assignment"
    with league.sessions() as session:
        settings2 = crud.default_assignment(session, course_id=course2).evaluation_settings()
    league.finish_job(course2_jobs[0], evaluation_outcome(2, EPISODES, settings2))  # course 2's own result

    with league.client(league.instructor_token) as instructor1:
        created = instructor1.post("/api/assignments", json={"name": unique("hw"), "episodes": EPISODES,
                                                             "due_at": DUE.isoformat()})
        assert created.status_code == 201, created.text
        hw = created.json()
        private_seed = instructor1.get(f"/api/assignments/{hw['id']}").json()["private_seed"]
        students = [league.user("s1")[0], league.user("s1b")[0]]
        submissions = [ready(league, student, hw["id"]) for student in students]
        championship = instructor1.post("/api/championships", json={"name": unique("cup"), "heat_size": 2}).json()
        started = instructor1.post(f"/api/championships/{championship['id']}/rounds")
        assert started.status_code == 202, started.text
        league.app.state.services.clock.set(DUE + timedelta(seconds=1))  # the due time passed: finals frozen
        catch_up(league.app.state.services)
        finals = private_evaluations(league, hw["id"])
        assert set(finals) == set(submissions)
        league.finish_job(finals[submissions[0]][1], private_outcome(private_seed, STUDENT_FIGURE))  # [1]: queued
        assert instructor1.put(f"/api/assignments/{hw['id']}/rubric", json=RUBRIC).status_code == 200
        baselines = private_evaluations(league, hw["id"], BASELINE)
        assert list(baselines) == [baseline], "the rubric queues the baseline's private test"
        league.finish_job(baselines[baseline][1], private_outcome(private_seed, BASELINE_FIGURE))
        assert instructor1.get(f"/api/assignments/{hw['id']}").json()["published_at"] is None
    secrets = [str(private_seed), *map(str, episode_seeds(private_seed, EPISODES)), str(STUDENT_FIGURE),
               str(BASELINE_FIGURE)]
    return TwoCourses(course1, course2, hw, private_seed, secrets, instructor2, student2, baseline, submissions,
                      students, started.json()["race_ids"], championship["id"], course2_jobs)


def course_state(league, course_id: int) -> dict:
    """Everything of a course that an action could change, as plain values."""
    with league.sessions() as session:
        people = [u.id for u in crud.course_users(session, course_id=course_id)]
        assignments = [a.id for a in crud.course_assignments(session, course_id=course_id)]

        def rows(query) -> list:
            return [tuple(row) for row in session.execute(query)]

        return {
            "course": rows(select(Course.name, Course.board_visibility).where(Course.id == course_id)),
            "users": rows(select(User.id, User.name, User.revoked_at, User.token_hash, User.display_name,
                                 User.active_submission_id).where(User.course_id == course_id).order_by(User.id)),
            "jobs": [(j.id, j.status, j.error) for j in crud.course_jobs(session, course_id=course_id, status=None,
                                                                        limit=100_000)],
            "evaluations": rows(select(Evaluation.id, Evaluation.status, Evaluation.track, Evaluation.result_key)
                                .where(Evaluation.course_id == course_id).order_by(Evaluation.id)),
            "assignments": rows(select(Assignment.id, Assignment.name, Assignment.description, Assignment.seed,
                                       Assignment.episodes, Assignment.due_at, Assignment.published_at,
                                       Assignment.rubric).where(Assignment.course_id == course_id)
                                .order_by(Assignment.id)),
            "student_assignments": rows(select(StudentAssignment.user_id, StudentAssignment.extension_due_at,
                                               StudentAssignment.selected_submission_id, StudentAssignment.final_at,
                                               StudentAssignment.final_submission_id)
                                        .where(StudentAssignment.assignment_id.in_(assignments))
                                        .order_by(StudentAssignment.id)),
            "submissions": rows(select(Submission.id, Submission.status, Submission.public, Submission.name)
                                .join(User, User.id == Submission.owner_id)
                                .where(Submission.owner_id.in_(people) | (User.role == BASELINE))
                                .order_by(Submission.id)),
            "championships": rows(select(Championship.id, Championship.name)
                                  .where(Championship.course_id == course_id)),
            "races": rows(select(Race.id, Race.status).where(Race.course_id == course_id).order_by(Race.id)),
            "audit": rows(select(AuditEvent.id).where(AuditEvent.course_id == course_id).order_by(AuditEvent.id)),
        }


def operations(app) -> list[tuple[str, str]]:
    """Every (method, path template) of the API's OpenAPI schema."""
    return [(method.upper(), template) for template, methods in app.openapi()["paths"].items()
            for method in methods]


def request_body(method: str, template: str, courses: TwoCourses) -> dict:
    """A well-formed body for the route (so that a refusal is about whose object it is, not a 422),
    naming course 1's objects wherever the body can name one."""
    hw, student_submission = courses.hw, courses.submissions[0]
    bodies = {
        ("POST", "/api/submissions"): {"files": {"file": ("agent.onnx", b"not really onnx")},
                                       "data": {"assignment": str(hw["id"])}},
        ("PATCH", "/api/submissions/{submission_id}"): {"json": {"public": True, "active": True}},
        ("POST", "/api/evaluations/rerun"): {"json": {"submission_id": student_submission}},
        ("PUT", "/api/settings/evaluation"): {"json": {"seed": 5, "episodes": 3, "env_options": {}}},
        ("POST", "/api/assignments"): {"json": {"name": hw["name"], "episodes": 3}},
        ("PATCH", "/api/assignments/{assignment_id}"): {"json": {"description": "taken over", "due_at": None}},
        ("PUT", "/api/assignments/{assignment_id}/extensions/{user_id}"): {
            "json": {"due_at": (DUE + timedelta(days=30)).isoformat()}},
        ("POST", "/api/assignments/{assignment_id}/selection"): {"json": {"submission_id": None}},
        ("PUT", "/api/assignments/{assignment_id}/rubric"): {"json": RUBRIC},
        ("POST", "/api/championships"): {"json": {"name": unique("cup"), "heat_size": 2, "assignment": hw["id"]}},
        ("POST", "/api/races"): {"json": {"submission_ids": courses.submissions}},
        ("POST", "/api/users"): {"json": {"name": unique("new")}},
        ("POST", "/api/users/roster"): {"files": {"file": ("roster.csv", f"name\n{unique('zed')}\n".encode())}},
        ("PUT", "/api/settings/privacy"): {"json": {"board_visibility": "members"}},
        ("PATCH", "/api/users/me"): {"json": {"display_name": courses.students[0].name}},
        ("POST", "/api/tracks/geometry"): {"json": {}},
    }
    return bodies.get((method, template), {})


class Answers(dict):
    """(method, path) -> response; `actions`: the requests of other methods whose path names course 1's objects."""

    actions: set[tuple[str, str]]


def walk(league, token: str, courses: TwoCourses) -> Answers:
    """Every route as `token`'s user: each GET path with course 1's ids (and the reads the issue
    names), each other method with course 1's ids and a body naming course 1's objects."""
    ids = courses.ids
    gets = [*every_get(league.app, ids),
            *(f"/api/submissions/{submission}/episodes?evaluation_id={evaluation}"
              for submission, evaluation in courses.ids["evaluations"]),
            "/api/jobs?limit=1000", "/api/submissions?all=true", f"/api/races?championship_id={courses.championship}",
            f"/api/assignments/{courses.hw['id']}/board?board=private",
            f"/api/assignments/{courses.hw['id']}/board.csv?board=private",
            f"/api/integrity?assignment={courses.hw['id']}", f"/api/integrity.csv?assignment={courses.hw['id']}",
            f"/api/championships/{courses.championship}/standings?size=100"]
    answers = Answers()
    answers.actions = set()
    with league.client(token) as client:
        for path in gets:
            answers["GET", path] = client.get(path)
        for method, template in operations(league.app):
            if method == "GET":
                continue
            for path in every_get_paths(template, ids):
                answers[method, path] = client.request(method, path, **request_body(method, template, courses))
                if "{" in template:
                    answers.actions.add((method, path))
    return answers


def every_get_paths(template: str, ids: dict) -> list[str]:
    """The template with each combination of course 1's ids (every_get's rule, for any method)."""
    names = re.findall(r"{(\w+)}", template)
    assert set(names) <= set(ids), f"{template}: which {set(names) - set(ids)}? add it to ids"
    return [template.format(**dict(zip(names, values))) for values in itertools.product(*(ids[n] for n in names))]


def test_another_courses_instructor_and_student_neither_read_nor_act_on_a_course(league):
    courses = two_courses(league)
    with league.sessions() as session:
        course1_jobs = [job.id for job in crud.course_jobs(session, course_id=courses.course1, status=None,
                                                           limit=100_000)]
        evaluations = list(session.execute(select(Evaluation.submission_id, Evaluation.id).where(
            Evaluation.course_id == courses.course1,
            Evaluation.submission_id.in_([courses.baseline, *courses.submissions]))))
        default1 = crud.default_assignment(session, course_id=courses.course1).id
        instructor1 = session.scalar(select(User.id).where(User.name == "prof"))
    assert len(private_evaluations(league, courses.hw["id"])) == 3  # the two finals' and the baseline's
    courses.ids = {"job_id": course1_jobs, "submission_id": [courses.baseline, *courses.submissions],
                   "assignment_id": [courses.hw["id"], default1],
                   "user_id": [s.id for s in courses.students] + [instructor1],
                   "championship_id": [courses.championship], "number": [1], "race_id": courses.race_ids,
                   "filename": ["none.whl"], "evaluations": evaluations}

    # the secrets are there to be found: course 1's instructor reads them
    with league.client(league.instructor_token) as instructor1_client:
        seen = "\n".join(instructor1_client.get(f"/api/submissions/{s}/episodes?evaluation_id={e}").text
                         for s, e in evaluations)
        seen += instructor1_client.get(f"/api/assignments/{courses.hw['id']}/grades.csv").text
        seen += instructor1_client.get(f"/api/assignments/{courses.hw['id']}").text
    assert [secret for secret in courses.secrets if secret not in seen] == []

    before = course_state(league, courses.course1)
    for token, who in ((courses.student2, "student"), (courses.instructor2, "instructor")):
        answers = walk(league, token, courses)
        leaks = {f"{method} {path} ({response.status_code})": found for (method, path), response in answers.items()
                 if (found := [secret for secret in courses.secrets if secret in response.text])}
        assert leaks == {}, f"course 2's {who} reads course 1's private test"
        refused = {f"{method} {path}": response.status_code for (method, path), response in answers.items()
                   if (method, path) in answers.actions and response.status_code not in (403, 404)}
        assert answers.actions and refused == {}, f"course 2's {who} acted on course 1's objects"
        jobs = answers["GET", "/api/jobs?limit=1000"]
        if who == "instructor":
            listed = {job["id"] for job in jobs.json()}
            assert listed & set(course1_jobs) == set() and set(courses.course2_jobs) <= listed
        else:
            assert jobs.status_code == 403
        for (method, path), response in answers.items():  # the body's own references to course 1's objects
            if (method, path) in (("POST", "/api/evaluations/rerun"), ("POST", "/api/races"),
                                  ("POST", "/api/championships"), ("POST", "/api/submissions")):
                assert response.status_code in (403, 404), (method, path, response.status_code, response.text)
    assert course_state(league, courses.course1) == before, "course 2's requests changed course 1"

    # the issue's own reads: a baseline's private episodes of course 1; its jobs; its re-run and cancel
    private_baseline = private_evaluations(league, courses.hw["id"], BASELINE)[courses.baseline][0]
    with league.client(courses.instructor2) as instructor2:
        assert instructor2.get(f"/api/submissions/{courses.baseline}/episodes",
                               params={"evaluation_id": private_baseline}).status_code == 404
        shown = instructor2.get(f"/api/submissions/{courses.baseline}").json()["evaluation"]
        with league.sessions() as session:
            assert session.get(Evaluation, shown["id"]).course_id == courses.course2  # its own result
        rerun = instructor2.post("/api/evaluations/rerun", json={"submission_id": courses.baseline})
        assert rerun.status_code == 202  # on course 2's settings, as course 2's evaluation
        assert course_state(league, courses.course1)["evaluations"] == before["evaluations"]
        queued = instructor2.get("/api/jobs", params={"status": "queued"}).json()
        rerun_job = next(job["id"] for job in queued if job["submission_id"] == courses.baseline)
        with league.client(league.instructor_token) as instructor1_client:  # nor the other way round
            assert instructor1_client.post(f"/api/jobs/{rerun_job}/cancel").status_code == 404
            assert rerun_job not in {job["id"] for job in instructor1_client.get("/api/jobs?limit=1000").json()}
        cancelled = instructor2.post(f"/api/jobs/{rerun_job}/cancel")
        assert cancelled.status_code == 200, cancelled.text  # course 2's own baseline job: its to cancel

    # the boards: course 2's result of the baseline (the same settings as course 1's default assignment)
    # ranks on course 2's board only; course 1 has not evaluated it on its default assignment yet
    def baseline_rows(token: str) -> list[tuple]:
        with league.client(token) as client:
            rows = client.get("/api/leaderboard", params={"size": 100}).json()["items"]
        return [(row["submission_id"], row["completed"]) for row in rows if row["submission_id"] == courses.baseline]

    assert (baseline_rows(league.instructor_token), baseline_rows(courses.instructor2)) == (
        [], [(courses.baseline, 2)])

    # the rule itself: course 1's private test shows to its own instructors, to others once published
    with league.sessions() as session:
        hw = session.get(Assignment, courses.hw["id"])
        instructor2_user = crud.user_by_token(session, token=courses.instructor2)
        instructor1_user = session.get(User, instructor1)
        assert (private_visible(hw, instructor1_user), private_visible(hw, instructor2_user)) == (True, False)
        hw.published_at = DUE + timedelta(days=1)
        assert private_visible(hw, instructor2_user)
        session.rollback()


def test_display_names_are_unique_within_a_course_only(league):
    with league.sessions.begin() as session:
        other, _ = add_course(session, name=unique("course"), settings=league.settings)
        other_id = other.id
    elsewhere, _ = league.user("login")  # of the first course
    user, token = league.user("kid", course_name=course_name(league, other_id))
    _, classmate = league.user("mate", course_name=course_name(league, other_id))
    with league.client(token) as client, league.client(classmate) as mate:
        assert client.patch("/api/users/me", json={"display_name": elsewhere.name}).status_code == 200
        taken = mate.patch("/api/users/me", json={"display_name": elsewhere.name.upper()})
        assert taken.status_code == 409 and "is taken" in taken.json()["detail"]
        assert mate.patch("/api/users/me", json={"display_name": user.name}).status_code == 409  # a classmate's login
        assert mate.patch("/api/users/me", json={"display_name": "baselines"}).status_code == 409  # on every board


def course_name(league, course_id: int) -> str:
    with league.sessions() as session:
        return session.get(Course, course_id).name
