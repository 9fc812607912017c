"""Grades over the API, in process on a real database of each backend: an assignment's finals frozen
at its due time and evaluated on its private tracks (the queue's jobs, finished through their
leases as a worker finishes them), graded under the rubric with the late penalty; the files
Canvas and Moodle import; who may see what."""
from __future__ import annotations

import csv
import io
import uuid
from dataclasses import dataclass, field
from datetime import datetime, timezone

from league.server.course.assignments import close_due
from league.server.db import crud
from league.server.db.models import (
    BASELINE, DONE, INSTRUCTOR, PRIVATE_TRACKS, READY, Assignment, Evaluation, Job, Submission, User,
)
from league.server.course.grading import CANVAS_STUDENT_COLUMNS, GENERIC_COLUMNS
from league.server.course.results import settings_key

from ...api_calls import unique
from ..in_process import evaluation_outcome

# due times no other test's assignment has: close_due, which closes every assignment whose time has
# passed, freezes only these
DUE, LATE_UNTIL, AFTER = (datetime(2001, 1, day, tzinfo=timezone.utc) for day in (1, 2, 3))
EPISODES = 4
RUBRIC = {"kind": "points", "max_points": 10, "completed": {"kind": "linear", "points": 6},
          "rank": {"kind": "table", "points": [4, 2, 1]}}


@dataclass
class Course:
    league: object
    instructor: object  # a client
    assignment: dict
    students: dict = field(default_factory=dict)  # name -> (User, client)

    def user(self, name: str) -> User:
        return self.students[name][0]

    def client(self, name: str):
        return self.students[name][1]


def new_course(app_league, names: list[str], **times) -> Course:
    course_name = unique("course")
    _, token = app_league.user("teacher", role=INSTRUCTOR, course_name=course_name)
    instructor = app_league.client(token)
    body = {"name": "Time trial", "seed": 5, "episodes": EPISODES, "due_at": DUE.isoformat(),
            "late_until": LATE_UNTIL.isoformat(), "late_penalty": 0.5, **times}
    response = instructor.post("/api/assignments", json=body)
    assert response.status_code == 201, response.text
    course = Course(app_league, instructor, response.json())
    for name in names:
        user, token = app_league.user(name, course_name=course_name)
        course.students[name] = (user, app_league.client(token))
    return course


def ready_submission(course: Course, name: str, completed: int, late: bool = False) -> int:
    """A ready submission of the student in the assignment, evaluated on its public tracks."""
    with course.league.sessions.begin() as session:
        assignment = session.get(Assignment, course.assignment["id"])
        owner = session.get(User, course.user(name).id)
        submission, _ = crud.create_submission(session, owner=owner, assignment=assignment, name=unique("agent"),
                                               filename="agent.onnx", kind="onnx", late=late,
                                               sha256=uuid.uuid4().hex.ljust(64, "0"), size=1, max_attempts=1)
        submission.status, submission.obs_dim = READY, 5
        settings = assignment.evaluation_settings()
        evaluation, _ = crud.create_evaluation(session, submission=submission, assignment=assignment,
                                               settings=settings, result_key=settings_key(settings), max_attempts=1)
        evaluation.status, evaluation.completed, evaluation.episodes_total = DONE, completed, EPISODES
        evaluation.mean_return, evaluation.mean_steps, evaluation.mean_speed = float(completed), 100.0, 0.3
        session.flush()
        return submission.id


def private_settings(course: Course) -> dict:
    with course.league.sessions() as session:
        return session.get(Assignment, course.assignment["id"]).private_settings()


def close_and_evaluate(course: Course, private: dict[str, int]) -> None:
    """The due time passes: every final is frozen and its private evaluation queued (as at start or
    on a reaper pass); each job then finishes with `private[student]` episodes completed."""
    with course.league.sessions.begin() as session:
        job_ids = close_due(session, now=AFTER, max_attempts=1)
    with course.league.sessions() as session:
        owners = {job_id: session.get(Submission, session.get(Job, job_id).submission_id).owner_id
                  for job_id in job_ids}
    students = {course.user(name).id: name for name in private}
    assert sorted(owners.values()) == sorted(students)
    settings = private_settings(course)
    for job_id, owner_id in owners.items():
        course.league.finish_job(job_id, evaluation_outcome(private[students[owner_id]], EPISODES, settings))


def set_identity(course: Course, name: str, email: str | None, student_id: str | None) -> None:
    with course.league.sessions.begin() as session:
        user = session.get(User, course.user(name).id)
        user.email, user.student_id = email, student_id


def grades(course: Course) -> dict:
    response = course.instructor.get(f"/api/assignments/{course.assignment['id']}/grades")
    assert response.status_code == 200, response.text
    return response.json()


def csv_rows(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


def graded_course(app_league) -> Course:
    """ann, bob (late), cy, eve (revoked after the due time) with finals; dee without one."""
    course = new_course(app_league, ["ann", "bob", "cy", "dee", "eve"])
    for name, completed, late in (("ann", 4, False), ("bob", 3, True), ("cy", 2, False), ("eve", 4, False)):
        ready_submission(course, name, completed, late)
    set_identity(course, "ann", "ann@uni.example", "S1")
    set_identity(course, "bob", "bob@uni.example", None)
    set_identity(course, "cy", None, "S3")
    response = course.instructor.put(f"/api/assignments/{course.assignment['id']}/rubric", json=RUBRIC)
    assert response.status_code == 200, response.text
    assert response.json()["rubric"] == {**RUBRIC, "completed": {**RUBRIC["completed"], "zero_at": 0.0, "full_at": 1.0}}
    close_and_evaluate(course, {"ann": 4, "bob": 3, "cy": 2, "eve": 4})
    response = course.instructor.post(f"/api/users/{course.user('eve').id}/revoke")
    assert response.status_code == 200, response.text
    return course


def test_finals_are_graded_on_their_private_results_ranked_among_students_with_the_late_penalty(app_league):
    course = graded_course(app_league)
    table = grades(course)
    assert (table["max_points"], table["late_penalty"], table["published"]) == (10, 0.5, False)
    rows = [(r["name"], r["status"], r["rank"], r["students"], r["completed"], r["late"], r["penalty"], r["points"],
             r["revoked"]) for r in table["rows"] if r["role"] == "student"]
    name = {n: course.user(n).name for n in course.students}
    assert rows == [
        (name["ann"], "graded", 1, 3, 1.0, False, 1.0, 10.0, False),  # 6 + 4
        (name["eve"], "graded", 1, 4, 1.0, False, 1.0, 10.0, True),  # revoked: ranked as if added alone
        (name["bob"], "graded", 2, 3, 0.75, True, 0.5, 3.25, False),  # (4.5 + 2) x 0.5
        (name["cy"], "graded", 3, 3, 0.5, False, 1.0, 4.0, False),  # 3 + 1
        (name["dee"], "no final", None, None, None, False, None, 0.0, False),
    ]


def test_the_baselines_are_reference_lines_once_evaluated_on_the_private_tracks(app_league):
    """Setting the rubric queues the baselines' private evaluations (low priority); once done, each
    is a line where its figures stand, without rank or grade."""
    course = graded_course(app_league)
    assert all(r["role"] == "student" for r in grades(course)["rows"])  # not evaluated yet
    with app_league.sessions.begin() as session:  # validated, as the bundled agents are once a worker runs
        for baseline in session.query(Submission).join(User, User.id == Submission.owner_id).filter(
                User.role == BASELINE):
            baseline.status, baseline.obs_dim = READY, 5
    response = course.instructor.put(f"/api/assignments/{course.assignment['id']}/rubric", json=RUBRIC)
    assert response.status_code == 200, response.text
    with app_league.sessions() as session:
        job_ids = [job_id for (job_id,) in session.query(Job.id)
                   .join(Evaluation, Evaluation.id == Job.evaluation_id)
                   .join(Submission, Submission.id == Evaluation.submission_id)
                   .join(User, User.id == Submission.owner_id)
                   .filter(User.role == BASELINE, Evaluation.track == PRIVATE_TRACKS,
                           Evaluation.assignment_id == course.assignment["id"], Job.status == "queued")]
    assert job_ids, "setting the rubric queues the baselines' private evaluations"
    for job_id in job_ids:
        app_league.finish_job(job_id, evaluation_outcome(3, EPISODES, private_settings(course)))
    rows = grades(course)["rows"]
    # ann and eve (1.0), bob (0.75), the baseline (0.75: after a student of equal figures), cy (0.5), dee
    assert [r["status"] for r in rows] == ["graded", "graded", "graded", "reference", "graded", "no final"]
    reference = rows[3]
    assert (reference["role"], reference["rank"], reference["points"], reference["completed"]) == \
        ("baseline", None, None, 0.75)
    assert [r["rank"] for r in rows if r["role"] == "student" and not r["revoked"]] == [1, 2, 3, None]

    # before publication, a student finds neither the baseline's private test nor the private seed
    with app_league.sessions() as session:
        evaluation = session.get(Job, job_ids[0]).evaluation_id
        baseline_id = session.get(Job, job_ids[0]).submission_id
        private_seed = session.get(Assignment, course.assignment["id"]).private_seed
    ann = course.client("ann")
    assert ann.get(f"/api/submissions/{baseline_id}/episodes", params={"evaluation_id": evaluation}).status_code == 404
    for path in (f"/api/assignments/{course.assignment['id']}", f"/api/assignments/{course.assignment['id']}/board",
                 "/api/leaderboard"):
        answer = ann.get(path)
        assert answer.status_code == 200 and str(private_seed) not in answer.text, path


def test_the_grade_files_parse_and_have_each_gradebooks_columns(app_league):
    course = graded_course(app_league)
    url = f"/api/assignments/{course.assignment['id']}/grades.csv"
    name = {n: course.user(n).name for n in course.students}

    generic = course.instructor.get(url)
    assert generic.status_code == 200 and generic.headers["content-type"] == "text/csv; charset=utf-8"
    lines = csv_rows(generic.text)
    assert lines[0] == GENERIC_COLUMNS
    table = {line[0]: dict(zip(GENERIC_COLUMNS, line)) for line in lines[1:]}
    assert {k: table[name["bob"]][k] for k in ("email", "late", "penalty", "points", "rank", "revoked")} == \
        {"email": "bob@uni.example", "late": "yes", "penalty": "0.5", "points": "3.25", "rank": "2", "revoked": ""}
    assert table[name["eve"]]["revoked"] == "yes" and table[name["dee"]]["status"] == "no final"

    canvas = course.instructor.get(url, params={"format": "canvas"})
    assert canvas.status_code == 200, canvas.text
    lines = csv_rows(canvas.text)
    assert lines[0] == CANVAS_STUDENT_COLUMNS + ["Time trial"]
    assert lines[1] == ["Points Possible", "", "", "", "", "10.0"]
    rows = {line[0]: line for line in lines[2:]}
    assert rows[name["ann"]] == [name["ann"], "", "S1", "ann@uni.example", "", "10.0"]
    assert rows[name["cy"]] == [name["cy"], "", "S3", "", "", "4.0"] and rows[name["dee"]][5] == "0.0"
    assert len(rows) == 5  # students only

    moodle = course.instructor.get(url, params={"format": "moodle"})
    assert csv_rows(moodle.text) == [["Email address", "Time trial"], ["ann@uni.example", "10.0"],
                                     ["bob@uni.example", "3.25"]]
    assert moodle.headers["x-left-out"] == "3"  # cy, dee, eve have no email
    by_id = course.instructor.get(url, params={"format": "moodle", "identifier": "idnumber"})
    assert csv_rows(by_id.text) == [["ID number", "Time trial"], ["S1", "10.0"], ["S3", "4.0"]]
    assert course.instructor.get(url, params={"format": "excel"}).status_code == 422


def test_students_see_only_their_own_grade_and_only_once_published(app_league):
    course = graded_course(app_league)
    assignment_id = course.assignment["id"]
    ann = course.client("ann")
    for path in (f"/api/assignments/{assignment_id}/grades", f"/api/assignments/{assignment_id}/grades.csv",
                 "/api/grades.csv"):
        response = ann.get(path)
        assert (response.status_code, response.json()["detail"]) == (403, "only instructors may do this")
    assert ann.put(f"/api/assignments/{assignment_id}/rubric", json=RUBRIC).status_code == 403
    early = ann.get(f"/api/assignments/{assignment_id}/grades/me")
    assert (early.status_code, early.json()["detail"]) == (404, "the grades of Time trial are not published")
    assert course.instructor.get(f"/api/assignments/{assignment_id}/grades/me").status_code == 403

    assert course.instructor.post(f"/api/assignments/{assignment_id}/publish").status_code == 200
    mine = ann.get(f"/api/assignments/{assignment_id}/grades/me")
    assert mine.status_code == 200, mine.text
    assert {k: mine.json()[k] for k in ("name", "rank", "points", "max_points", "assignment")} == \
        {"name": course.user("ann").name, "rank": 1, "points": 10.0, "max_points": 10, "assignment": "Time trial"}
    bob = course.client("bob").get(f"/api/assignments/{assignment_id}/grades/me").json()
    assert (bob["points"], bob["late"], bob["penalty"]) == (3.25, True, 0.5)

    outsider = new_course(app_league, [])
    assert outsider.instructor.get(f"/api/assignments/{assignment_id}/grades").status_code == 404


def test_a_rubric_is_checked_when_set_and_grades_need_one(app_league):
    course = new_course(app_league, ["ann"])
    url = f"/api/assignments/{course.assignment['id']}"
    response = course.instructor.get(f"{url}/grades")
    assert (response.status_code, response.json()["detail"]) == (
        409, f"Time trial has no rubric yet: set one (PUT /api/assignments/{course.assignment['id']}/rubric)")
    response = course.instructor.put(f"{url}/rubric", json={"kind": "formula", "max_points": 10,
                                                            "formula": "10 * completed / mean_speed"})
    assert (response.status_code, response.json()["detail"]) == (
        422, "formula.formula: the formula divides by zero when completed=0, mean_speed=0, rank=1, students=1")
    response = course.instructor.put(f"{url}/rubric", json={"kind": "formula", "max_points": 10,
                                                            "formula": "__import__('os')"})
    assert response.status_code == 422 and "may call only min(), max(), clip()" in response.text
    assert course.instructor.get(url).json()["rubric"] is None
    formula = {"kind": "formula", "max_points": 10, "formula": "10 * completed ** 2"}
    assert course.instructor.put(f"{url}/rubric", json=formula).json()["rubric"] == formula
    assert course.client("ann").get(url).json()["rubric"] == formula  # students read how they are graded
    assert [r["status"] for r in grades(course)["rows"]] == ["open"]  # before the due time


def test_grades_never_mix_results_of_two_settings(app_league):
    """After the assignment's settings change, a final evaluated with the old ones is stale (no
    grade, no rank) until it is evaluated with the new ones; ranks count only those."""
    course = new_course(app_league, ["ann", "bob"])
    ready_submission(course, "ann", 2)
    ready_submission(course, "bob", 4)
    course.instructor.put(f"/api/assignments/{course.assignment['id']}/rubric", json=RUBRIC)
    close_and_evaluate(course, {"ann": 2, "bob": 4})
    assert [(r["status"], r["rank"]) for r in grades(course)["rows"]] == [("graded", 1), ("graded", 2)]

    response = course.instructor.patch(f"/api/assignments/{course.assignment['id']}", json={"episodes": 8})
    assert response.status_code == 200, response.text
    assert [(r["status"], r["rank"], r["points"]) for r in grades(course)["rows"]] == [
        ("stale", None, None), ("stale", None, None)]

    # saving the rubric again queues the stale finals' private evaluations with the new settings
    settings = private_settings(course)
    assert course.instructor.put(f"/api/assignments/{course.assignment['id']}/rubric", json=RUBRIC).status_code == 200
    with app_league.sessions() as session:
        queued = dict(session.query(Submission.owner_id, Job.id).join(Job, Job.submission_id == Submission.id)
                      .join(Evaluation, Evaluation.id == Job.evaluation_id)
                      .filter(Evaluation.assignment_id == course.assignment["id"], Evaluation.track == PRIVATE_TRACKS,
                              Evaluation.result_key == settings_key(settings), Job.status == "queued").all())
    assert {course.user("ann").id, course.user("bob").id} <= set(queued)
    app_league.finish_job(queued[course.user("ann").id], evaluation_outcome(6, 8, settings))  # ann's runs first
    rows = grades(course)["rows"]
    assert [(r["name"], r["status"], r["rank"], r["students"], r["completed"]) for r in rows] == [
        (course.user("ann").name, "graded", 1, 1, 0.75), (course.user("bob").name, "stale", None, None, None)]


def test_the_course_file_has_a_column_an_assignment_and_the_total(app_league):
    course = graded_course(app_league)
    second = course.instructor.post("/api/assignments", json={
        "name": "Obstacles", "seed": 6, "episodes": EPISODES, "due_at": DUE.isoformat()}).json()
    course.instructor.post("/api/assignments", json={"name": "No rubric yet", "seed": 7, "episodes": 1})
    formula = {"kind": "formula", "max_points": 5, "formula": "5 * completed"}
    assert course.instructor.put(f"/api/assignments/{second['id']}/rubric", json=formula).status_code == 200
    course.assignment = second
    ready_submission(course, "ann", 2)
    close_and_evaluate(course, {"ann": 2})

    lines = csv_rows(course.instructor.get("/api/grades.csv").text)
    assert lines[0] == ["name", "email", "student_id", "revoked", "Time trial", "Obstacles", "total"]
    assert lines[1] == ["Points Possible", "", "", "", "10.0", "5.0", "15.0"]
    table = {line[0]: line[3:] for line in lines[2:]}
    name = {n: course.user(n).name for n in course.students}
    assert table[name["ann"]] == ["", "10.0", "2.5", "12.5"]
    assert table[name["bob"]] == ["", "3.25", "0.0", "3.25"]  # no final in Obstacles
    assert table[name["eve"]] == ["yes", "10.0", "0.0", "10.0"]  # revoked before Obstacles closed: no final
    canvas = csv_rows(course.instructor.get("/api/grades.csv", params={"format": "canvas"}).text)
    assert canvas[0] == CANVAS_STUDENT_COLUMNS + ["Time trial", "Obstacles"]
