"""Assignments on the real app and database (both backends), with the server's clock held by the test:
upload windows to the second, extensions, late windows, daily quotas; the final choice; the private
test at the due time (also after a server stopped across it); no leak of the private tracks before
publication; the migration of a course into its default assignment."""
from __future__ import annotations

import re
import uuid
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from league.evaluation import episode_seeds, league_versions
from league.server.app import create_app
from league.server.db import crud
from league.server.db.models import (
    DONE, INSTRUCTOR, PRIVATE_TRACKS, READY, Assignment, Evaluation, Job, StudentAssignment, User,
)
from league.server.course.results import settings_key
from league.server.jobs.evaluate import EvaluationOutcome

from ...api_calls import unique
from ...backends import BACKENDS
from ..in_process import in_process_league

T0 = datetime(2030, 3, 1, 9, 0, tzinfo=timezone.utc)  # opens
T1 = datetime(2030, 3, 8, 23, 59, tzinfo=timezone.utc)  # due
T2 = datetime(2030, 3, 10, 23, 59, tzinfo=timezone.utc)  # late window ends
SECOND = timedelta(seconds=1)
CONTRACT = Path(__file__).parents[4] / "docs" / "CONTRACT.md"


@pytest.fixture(scope="module", params=BACKENDS)
def league(request, tmp_path_factory):
    """A league of its own: these tests move its clock and add assignments."""
    with in_process_league(request.param, tmp_path_factory.mktemp(f"assignments-{request.param}"),
                           quota_per_day=1000) as league_:
        yield league_


@pytest.fixture(autouse=True)
def clock(league):
    yield league.app.state.services.clock
    league.app.state.services.clock.set(None)


def create(league, **fields) -> dict:
    body = {"name": unique("hw"), "episodes": 4, **fields}
    body = {k: v.isoformat() if isinstance(v, datetime) else v for k, v in body.items()}
    with league.client(league.instructor_token) as instructor:
        response = instructor.post("/api/assignments", json=body)
    assert response.status_code == 201, response.text
    return response.json()


def upload(client, assignment: str | int | None = None):
    data = {} if assignment is None else {"assignment": str(assignment)}
    return client.post("/api/submissions", files={"file": ("agent.onnx", b"not really onnx")}, data=data)


def ready(league, owner: User, assignment_id: int, completed: int) -> int:
    """A ready submission of the assignment with a finished public evaluation (`completed` of 4)."""
    with league.sessions.begin() as session:
        assignment = session.get(Assignment, assignment_id)
        submission, _ = crud.create_submission(session, owner=session.get(User, owner.id), assignment=assignment,
                                               name=unique("agent"), filename="a.onnx", kind="onnx",
                                               sha256=uuid.uuid4().hex.ljust(64, "0"), size=1, max_attempts=1)
        submission.status, submission.obs_dim = READY, 5
        settings = assignment.evaluation_settings()
        evaluation, _ = crud.create_evaluation(session, submission=submission, assignment=assignment,
                                               settings=settings, result_key=settings_key(settings), max_attempts=1)
        evaluation.status, evaluation.completed, evaluation.episodes_total = DONE, completed, 4
        evaluation.mean_return, evaluation.mean_steps, evaluation.mean_speed = completed * 2.0, 500.0, 0.3
        session.flush()
        return submission.id


def test_uploads_are_decided_by_the_servers_clock_to_the_second(league, clock):
    hw = create(league, opens_at=T0, due_at=T1, late_until=T2, late_penalty=0.5)
    extended_student, extended = league.student("ext")
    _, student = league.student()
    with league.client(league.instructor_token) as instructor:
        response = instructor.put(f"/api/assignments/{hw['id']}/extensions/{extended_student.id}",
                                  json={"due_at": (T2 + timedelta(days=2)).isoformat()})
        assert response.status_code == 200 and response.json()["due_at"] == "2030-03-12T23:59:00+00:00"
    clock.set(T0 - SECOND)
    refused = upload(student, hw["name"])
    assert (refused.status_code, refused.json()["detail"]) == (403, f"{hw['name']} opens for uploads at "
                                                                    "2030-03-01T09:00:00+00:00")
    clock.set(T1 - SECOND)
    on_time = upload(student, hw["id"])
    assert on_time.status_code == 201, on_time.text
    clock.set(T1 + SECOND)
    late = upload(student, hw["name"])
    assert late.status_code == 201
    mine = {s["id"]: s for s in student.get("/api/submissions").json()}
    assert (mine[on_time.json()["id"]]["late"], mine[late.json()["id"]]["late"]) == (False, True)
    assert mine[late.json()["id"]]["assignment_id"] == hw["id"]
    assert student.get(f"/api/assignments/{hw['id']}").json()["state"] == "late"
    clock.set(T2 + SECOND)
    closed = upload(student, hw["name"])
    assert (closed.status_code, closed.json()["detail"]) == (403, f"{hw['name']} closed for your uploads at "
                                                                   "2030-03-10T23:59:00+00:00")
    extended_upload = upload(extended, hw["name"])  # their own due time: still on time
    assert extended_upload.status_code == 201
    own = extended.get(f"/api/assignments/{hw['id']}").json()
    assert (own["my_due_at"], own["extended"], own["state"]) == ("2030-03-12T23:59:00+00:00", True, "open")
    assert extended.get(f"/api/submissions/{extended_upload.json()['id']}").json()["late"] is False


def test_without_a_late_window_the_due_time_closes_uploads(league, clock):
    hw = create(league, due_at=T1)
    _, student = league.student()
    clock.set(T1 - SECOND)
    assert upload(student, hw["name"]).status_code == 201
    clock.set(T1 + SECOND)
    response = upload(student, hw["name"])
    assert (response.status_code, response.json()["detail"]) == (403, f"{hw['name']} closed for your uploads at "
                                                                      "2030-03-08T23:59:00+00:00")


def test_the_daily_quota_counts_per_utc_day_and_says_when_it_resets(league, clock):
    hw = create(league, daily_quota=2)
    _, student = league.student()
    clock.set(datetime(2030, 3, 2, 22, 0, tzinfo=timezone.utc))
    assert [upload(student, hw["name"]).status_code for _ in range(2)] == [201, 201]
    third = upload(student, hw["name"])
    assert third.status_code == 429
    assert third.json()["detail"].endswith("it resets at 2030-03-03T00:00:00+00:00")
    clock.set(datetime(2030, 3, 3, 0, 0, 1, tzinfo=timezone.utc))
    assert upload(student, hw["name"]).status_code == 201


def test_without_an_assignment_named_an_upload_goes_to_the_only_open_one(league, clock):
    clock.set(datetime(2040, 1, 1, tzinfo=timezone.utc))  # every earlier test's assignment is closed
    _, student = league.student()
    first, second = create(league), create(league)  # open for good (no due time)
    several = upload(student)
    assert several.status_code == 422 and several.json()["detail"].startswith("several assignments are open: ")
    assert first["name"] in several.json()["detail"] and second["name"] in several.json()["detail"]
    assert "default" not in several.json()["detail"]  # the automatic one closed when the first hw was made
    unknown = upload(student, "no such homework")
    assert (unknown.status_code, unknown.json()["detail"]) == (
        404, "no assignment 'no such homework' in your course (see `league assignments`)")


def test_the_automatic_assignment_closes_once_the_instructor_makes_one_unless_kept_open(league, monkeypatch,
                                                                                          capsys, tmp_path):
    """Issue 30: a new course's `default` takes uploads until its instructor creates an assignment; then
    an upload without an assignment goes to theirs (API and `league submit`), and `default` refuses
    students, unless the instructor keeps it open; then several are open and the upload must name one."""
    from league.client.api import Api
    from league.cli import main
    from league.exit_codes import EXIT_ERROR

    course = unique("course")
    _, prof_token = league.user("prof", role=INSTRUCTOR, course_name=course)
    _, student_token = league.user("stu", course_name=course)
    with league.client(prof_token) as prof, league.client(student_token) as student:
        [automatic] = student.get("/api/assignments").json()
        assert (automatic["name"], automatic["automatic"], automatic["keep_open"], automatic["state"]) == (
            "default", True, False, "open")
        alone = upload(student)
        assert alone.status_code == 201, alone.text
        sprint = prof.post("/api/assignments", json={"name": "Sprint", "episodes": 4}).json()
        assert (sprint["automatic"], sprint["keep_open"]) == (False, False)
        assert {a["name"]: a["state"] for a in student.get("/api/assignments").json()} == {
            "default": "closed", "Sprint": "open"}
        to_sprint = upload(student)
        assert to_sprint.status_code == 201, to_sprint.text
        refused = upload(student, "default")
        assert (refused.status_code, refused.json()["detail"]) == (
            403, "default takes no more uploads: the course's assignments are Sprint "
                 "(`league submit FILE --assignment NAME`)")
        assert upload(prof, "default").status_code == 201  # an instructor's upload is never refused
        assert prof.patch(f"/api/assignments/{sprint['id']}", json={"keep_open": True}).status_code == 422
        assert student.patch(f"/api/assignments/{automatic['id']}", json={"keep_open": True}).status_code == 403
        kept = prof.patch(f"/api/assignments/{automatic['id']}", json={"keep_open": True})
        assert kept.status_code == 200 and kept.json()["keep_open"] is True
        assert student.get(f"/api/assignments/{automatic['id']}").json()["state"] == "open"
        several = upload(student)
        assert (several.status_code, several.json()["detail"]) == (
            422, "several assignments are open: default, Sprint: name one (the form field `assignment`, or "
                 "`league submit FILE --assignment NAME`)")
        assert upload(student, "default").status_code == 201
        mine = {s["id"]: s["assignment_id"] for s in student.get("/api/submissions").json()}
    assert (mine[alone.json()["id"]], mine[to_sprint.json()["id"]]) == (automatic["id"], sprint["id"])

    # `league submit` without --assignment: the list and the flag to use, before anything is uploaded
    monkeypatch.setattr(Api, "__init__",
                        lambda self, conn, timeout=60: setattr(self, "conn", conn) or setattr(
                            self, "http", league.client(conn.token)))
    monkeypatch.setenv("LEAGUE_SERVER", "http://testserver")
    monkeypatch.setenv("LEAGUE_TOKEN", student_token)
    model = tmp_path / "agent.onnx"
    model.write_bytes(b"not really onnx")
    capsys.readouterr()
    assert main(["submit", str(model), "--no-check"]) == EXIT_ERROR
    assert capsys.readouterr().err == ("league: error: several assignments are open to you: default, Sprint; say "
                                       "which with --assignment NAME, e.g. league submit FILE --assignment default\n")
    assert len(mine) == len(league.client(student_token).get("/api/submissions").json())  # nothing uploaded
    monkeypatch.setenv("LEAGUE_TOKEN", prof_token)
    assert main(["assignments", "edit", "default", "--no-keep-open"]) == 0
    assert main(["assignments", "--csv"]) == 0
    listing = capsys.readouterr().out
    assert '"default (automatic)","closed"' in listing and '"Sprint","open"' in listing
    monkeypatch.setenv("LEAGUE_TOKEN", student_token)
    assert main(["submit", str(model), "--no-check"]) == 0
    said = capsys.readouterr()
    assert "for the assignment Sprint (the only one open to you)" in said.err
    with league.client(student_token) as student:
        assert student.get(f"/api/submissions/{int(said.out)}").json()["assignment_id"] == sprint["id"]


def private_outcome(assignment: dict, completed: int, mean_return: float) -> EvaluationOutcome:
    """What the private evaluation job returns: the private tracks' real episode seeds, made-up figures."""
    settings = {"seed": assignment["private_seed"], "episodes": assignment["episodes"],
                "env_options": assignment["env_options"]}
    seeds = episode_seeds(settings["seed"], settings["episodes"])
    rows = [{"seed": seed, "steps": 100, "return": mean_return, "mean_speed": 0.3,
             "outcome": "finished" if i < completed else "off_road", "reason": None} for i, seed in enumerate(seeds)]
    record = {**settings, "versions": league_versions(), "result_key": settings_key(settings)}
    return EvaluationOutcome({"episodes": rows, "completed": completed, "episodes_total": len(rows),
                              "mean_return": mean_return, "mean_steps": 100.0, "mean_speed": 0.3,
                              "settings": record}, None, f"private run of seed {settings['seed']}")


def private_jobs(league, assignment_id: int) -> dict[int, int]:
    """The assignment's private evaluation jobs: submission id -> job id."""
    with league.sessions() as session:
        rows = session.execute(
            crud.select(Job.submission_id, Job.id).join(Evaluation, Job.evaluation_id == Evaluation.id)
            .where(Evaluation.assignment_id == assignment_id, Evaluation.track == PRIVATE_TRACKS))
        return dict(rows.all())


def contract_gets() -> list[str]:
    """Every GET route docs/CONTRACT.md lists, without its query."""
    routes = re.findall(r"GET\s+(/api/[^\s`?]+)", CONTRACT.read_text())
    assert len(routes) > 15, "the route list was not found in docs/CONTRACT.md"
    return sorted(set(routes))


def walk(client, routes: list[str], ids: dict[str, int], extra: list[str]) -> str:
    """Every answer of `routes` (ids filled in) and of `extra`, as one text."""
    answers = []
    for route in routes:
        path = route
        for name, value in ids.items():
            path = path.replace("{" + name + "}", str(value))
        path = re.sub(r"\{[a-z_]+\}", "1", path)
        answers.append(client.get(path).text)
    for path in extra:
        answers.append(client.get(path).text)
    for page in ("/", "/submissions", "/instructor", "/races/1"):
        answers.append(client.get(page).text)
    return "\n".join(answers)


def test_finals_are_frozen_at_the_due_time_tested_privately_and_shown_only_once_published(league, clock):
    hw = create(league, due_at=T1, episodes=5)
    with league.client(league.instructor_token) as instructor:
        private_seed = instructor.get(f"/api/assignments/{hw['id']}").json()["private_seed"]
    hw["private_seed"] = private_seed
    chooser_user, chooser = league.student("chooser")
    best_user, best = league.student("best")
    _, idle = league.student("idle")
    chosen = ready(league, chooser_user, hw["id"], completed=1)
    ready(league, chooser_user, hw["id"], completed=4)
    weaker = ready(league, best_user, hw["id"], completed=2)
    strongest = ready(league, best_user, hw["id"], completed=3)
    clock.set(T1 - SECOND)
    selected = chooser.post(f"/api/assignments/{hw['id']}/selection", json={"submission_id": chosen})
    assert selected.status_code == 200 and selected.json()["final"] == {
        "submission_id": chosen, "selected": True, "frozen_at": None, "decided": False, "evaluation": None}
    assert best.post(f"/api/assignments/{hw['id']}/selection",
                     json={"submission_id": chosen}).status_code == 404  # not theirs
    assert best.get(f"/api/assignments/{hw['id']}").json()["final"]["submission_id"] == strongest
    assert best.get(f"/api/assignments/{hw['id']}").json()["private_seed"] is None

    clock.set(T1 + SECOND)  # the due time passed: the API's start or the reaper's pass freezes the finals
    from league.server.app import catch_up

    assert catch_up(league.app.state.services) and not catch_up(league.app.state.services)  # idempotent
    jobs = private_jobs(league, hw["id"])
    assert set(jobs) == {chosen, strongest}
    late_change = chooser.post(f"/api/assignments/{hw['id']}/selection", json={"submission_id": None})
    assert (late_change.status_code, late_change.json()["detail"]) == (
        409, f"your final submission of {hw['name']} was frozen at 2030-03-08T23:59:00+00:00")
    league.finish_job(jobs[chosen], private_outcome(hw, completed=5, mean_return=777.125))
    league.finish_job(jobs[strongest], private_outcome(hw, completed=2, mean_return=333.375))
    with league.sessions() as session:
        evaluation_ids = {row.final_submission_id: row.final_evaluation_id for row in session.scalars(
            crud.select(StudentAssignment).where(StudentAssignment.assignment_id == hw["id"]))}

    # before publication: nothing a student can obtain shows the private seed, tracks or figures
    secrets_ = [str(private_seed), *map(str, episode_seeds(private_seed, 5)), "777.125", "333.375",
                "seed " + str(private_seed)]
    extra = [f"/api/assignments/{hw['id']}/board?board=private", f"/api/assignments/{hw['id']}/board.csv?board=private",
             f"/api/submissions/{chosen}/episodes?evaluation_id={evaluation_ids[chosen]}",
             f"/api/submissions/{chosen}/episodes", "/api/submissions", "/api/assignments", "/api/leaderboard.csv",
             f"/api/assignments/{hw['id']}/board.csv", "/openapi.json"]
    ids = {"id": hw["id"], "user_id": chooser_user.id, "filename": "none"}
    for client, submission_id in ((chooser, chosen), (best, weaker), (idle, chosen)):
        text = (walk(client, contract_gets(), {**ids, "id": submission_id}, extra)
                + walk(client, contract_gets(), ids, []))
        assert [secret for secret in secrets_ if secret in text] == []
    assert chooser.get(extra[0]).status_code == 404
    assert chooser.get(extra[2]).status_code == 404
    with league.client(league.instructor_token) as instructor:  # instructors see the private board at once
        csv_text = instructor.get(f"/api/assignments/{hw['id']}/board.csv?board=private").text
        assert "777.125" in csv_text
        assert instructor.post(f"/api/assignments/{hw['id']}/publish").status_code == 200

    # after: each student sees their own private result and episodes, and the private board
    final = chooser.get(f"/api/assignments/{hw['id']}").json()["final"]
    assert (final["submission_id"], final["evaluation"]["mean_return"], final["frozen_at"]) == (
        chosen, 777.125, "2030-03-08T23:59:00+00:00")
    episodes = chooser.get(f"/api/submissions/{chosen}/episodes?evaluation_id={evaluation_ids[chosen]}").json()
    assert [row["seed"] for row in episodes["items"]] == episode_seeds(private_seed, 5)
    board = idle.get(f"/api/assignments/{hw['id']}/board?board=private").json()
    assert [(row["submission_id"], row["completed"]) for row in board["items"]] == [(chosen, 5), (strongest, 2)]
    assert idle.get(f"/api/assignments/{hw['id']}").json()["private_seed"] == private_seed


def test_a_server_stopped_across_a_due_time_evaluates_the_finals_when_it_starts(league, clock):
    hw = create(league, due_at=T1, auto_publish=True)
    student_user, _ = league.student()
    agent = ready(league, student_user, hw["id"], completed=3)
    restarted = create_app(league.settings)
    restarted.state.services.clock.set(T1 + timedelta(days=3))  # it starts three days after the due time
    with TestClient(restarted):
        pass
    restarted.state.services.engine.dispose()
    jobs = private_jobs(league, hw["id"])
    assert list(jobs) == [agent]
    with league.sessions() as session:
        row = crud.student_assignment(session, assignment_id=hw["id"], user_id=student_user.id)
        assert row.final_at == T1 and row.final_submission_id == agent  # frozen at the due time, not at the start
    # every final evaluated: the next pass publishes it (auto_publish), for every student in the course
    with league.sessions() as session:
        others = [u.id for u in crud.active_students(session, course_id=hw_course(session, hw))]
    assert student_user.id in others
    clock.set(datetime(2040, 1, 1, tzinfo=timezone.utc))
    from league.server.app import catch_up

    catch_up(league.app.state.services)  # earlier tests' students without a final are frozen too
    for job_id in private_jobs(league, hw["id"]).values():
        with league.sessions() as session:
            if session.get(Job, job_id).status == "queued":
                league.finish_job(job_id, private_outcome({**hw, "private_seed": private_seed_of(league, hw)}, 2, 1.5))
    catch_up(league.app.state.services)
    with league.client(league.instructor_token) as instructor:
        assert instructor.get(f"/api/assignments/{hw['id']}").json()["published_at"] == "2040-01-01T00:00:00+00:00"


def hw_course(session, hw: dict) -> int:
    return session.get(Assignment, hw["id"]).course_id


def private_seed_of(league, hw: dict) -> int:
    with league.sessions() as session:
        return session.get(Assignment, hw["id"]).private_seed


def test_publishing_waits_for_every_students_close_time(league, clock):
    hw = create(league, due_at=T1)
    student_user, _ = league.student("slow")
    with league.client(league.instructor_token) as instructor:
        instructor.put(f"/api/assignments/{hw['id']}/extensions/{student_user.id}",
                       json={"due_at": (T1 + timedelta(days=1)).isoformat()})
        clock.set(T1 + SECOND)
        response = instructor.post(f"/api/assignments/{hw['id']}/publish")
        assert response.status_code == 409 and student_user.name in response.json()["detail"]
        assert instructor.get(f"/api/assignments/{hw['id']}").json()["published_at"] is None


def test_assignment_settings_are_validated_and_names_unique(league):
    with league.client(league.instructor_token) as instructor:
        naive = instructor.post("/api/assignments", json={"name": unique("a"), "due_at": "2030-03-08T23:59:00"})
        assert naive.status_code == 422
        backwards = instructor.post("/api/assignments", json={"name": unique("a"), "due_at": T1.isoformat(),
                                                             "late_until": T0.isoformat()})
        assert (backwards.status_code, "late_until needs a due_at before it" in backwards.text) == (422, True)
        assert instructor.post("/api/assignments", json={"name": "default"}).status_code == 409
        zone = instructor.post("/api/assignments", json={"name": unique("z"), "due_at": "2030-03-09T00:59:00+01:00"})
        assert zone.json()["due_at"] == "2030-03-08T23:59:00+00:00"
    _, student = league.student()
    assert student.post("/api/assignments", json={"name": unique("a")}).status_code == 403


def test_the_cli_creates_extends_lists_and_selects(league, clock, monkeypatch, capsys):
    """`league assignments create|extend|publish`, `league assignments`, `league select`, against the app
    itself (the CLI's HTTP client given the app's transport)."""
    from league.client.api import Api
    from league.cli import main
    from league.exit_codes import EXIT_REFUSED

    def api_on_the_app(self, conn, timeout: float = 60):
        self.conn, self.http = conn, league.client(conn.token)

    monkeypatch.setattr(Api, "__init__", api_on_the_app)
    monkeypatch.setenv("LEAGUE_SERVER", "http://testserver")
    student_user, student_token = league.user("cli")
    name = unique("cli-hw")

    def league_cli(token: str, *args: str) -> str:
        monkeypatch.setenv("LEAGUE_TOKEN", token)
        assert main(list(args)) == 0
        return capsys.readouterr().out

    clock.set(T0)
    league_cli(league.instructor_token, "assignments", "create", name, "--due", T1.isoformat(), "--episodes", "3")
    league_cli(league.instructor_token, "assignments", "extend", name, student_user.name,
               "--due", "2030-03-09T23:59:00+00:00")
    with league.sessions() as session:
        assignment_id = [a.id for a in crud.course_assignments(session, course_id=student_user.course_id)
                         if a.name == name][0]
    agent = ready(league, student_user, assignment_id, completed=2)
    listing = league_cli(student_token, "assignments", "--csv")
    row = [line for line in listing.splitlines() if name in line][0]
    assert "(extension)" in row and ",\"open\"," in row and "8d 14h 59m" in row  # 2030-03-01 09:00 to 03-09 23:59
    selected = league_cli(student_token, "select", str(agent))
    assert f"your final submission is {agent}" in selected
    monkeypatch.setenv("LEAGUE_TOKEN", league.instructor_token)
    assert main(["assignments", "publish", name]) == EXIT_REFUSED  # students may still upload


def test_an_assignments_board_is_shown_as_the_courses_board_visibility_allows(league):
    """Members only (the default): a visitor is asked to log in, a member sees the board; public:
    visitors see it too."""
    hw = create(league)
    with league.client(league.instructor_token) as instructor, league.client() as visitor:
        before = instructor.get("/api/settings/privacy").json()
        assert before["board_visibility"] == "members"  # a new course's
        assert visitor.get(f"/api/assignments/{hw['id']}/board").status_code == 401
        _, student = league.student()
        assert student.get(f"/api/assignments/{hw['id']}/board").status_code == 200
        instructor.put("/api/settings/privacy", json={**before, "board_visibility": "public"}).raise_for_status()
        try:
            assert visitor.get(f"/api/assignments/{hw['id']}/board").status_code == 200
        finally:
            instructor.put("/api/settings/privacy", json=before).raise_for_status()


def test_a_championship_of_an_assignment_races_the_final_choices_not_the_active_submissions(league, clock):
    """The round's entrants follow final_choices (the private test's and the grades' rule): the
    selected submission, else the best on the assignment's board; a championship without an
    assignment still races each student's active submission."""
    hw = create(league)
    chooser_user, chooser = league.student("racer")
    best_user, _ = league.student("racer")
    selected = ready(league, chooser_user, hw["id"], completed=1)
    active = ready(league, chooser_user, hw["id"], completed=4)  # their best, and their active submission
    weaker = ready(league, best_user, hw["id"], completed=2)
    strongest = ready(league, best_user, hw["id"], completed=3)
    assert chooser.patch(f"/api/submissions/{active}", json={"active": True}).status_code == 200
    assert chooser.post(f"/api/assignments/{hw['id']}/selection", json={"submission_id": selected}).status_code == 200

    def first_round_entrants(**body) -> set[int]:
        with league.client(league.instructor_token) as instructor:
            created = instructor.post("/api/championships", json={"name": unique("cup"), "heat_size": 10,
                                                                  "include_baselines": False, **body})
            assert created.status_code == 201, created.text
            assert created.json()["assignment_id"] == body.get("assignment")
            started = instructor.post(f"/api/championships/{created.json()['id']}/rounds")
            assert started.status_code == 202, started.text
            return {i for heat in started.json()["heats"] for i in heat}

    of_hw = first_round_entrants(assignment=hw["id"])
    assert of_hw == {selected, strongest}  # other students of the module have no submission of hw
    of_course = first_round_entrants()
    assert active in of_course and selected not in of_course and weaker not in of_course

    with league.client(league.instructor_token) as instructor:
        unknown = instructor.post("/api/championships", json={"name": unique("cup"), "assignment": 999999})
    assert (unknown.status_code, unknown.json()["detail"]) == (404, "no assignment 999999 in your course")


def test_a_finals_private_test_is_not_its_owners_job_in_flight_nor_takes_their_turn(league, clock, monkeypatch):
    """At the due time the student's private test is queued under their id (whose final), yet it is the
    league's job: their next upload is not refused for it (the 429 counts their own jobs only) and
    waits behind no job of theirs in the queue (the private test takes a turn of its own)."""
    from league.server.app import catch_up
    from league.server.jobs.leases import fairest_queued

    monkeypatch.setattr(league.app.state.services.settings, "max_jobs_in_flight", 1)
    hw = create(league, due_at=T1)
    with league.client(league.instructor_token) as instructor:  # her later uploads go there, past hw's due time
        default = next(a for a in instructor.get("/api/assignments").json() if a["automatic"])
        assert instructor.patch(f"/api/assignments/{default['id']}", json={"keep_open": True}).status_code == 200
    dora_user, dora = league.student("dora")
    _, ann = league.student("ann")
    ready(league, dora_user, hw["id"], completed=3)
    with league.sessions.begin() as session:  # her jobs so far over: only what follows is in flight
        session.execute(Job.__table__.update().where(Job.owner_id == dora_user.id).values(status=DONE))
    clock.set(T1 + SECOND)
    catch_up(league.app.state.services)
    (private,) = private_jobs(league, hw["id"]).values()
    first, second = upload(dora, "default"), upload(dora, "default")
    from_ann = upload(ann, "default")
    with league.sessions() as session:
        owner, status = session.execute(crud.select(Job.owner_id, Job.status).where(Job.id == private)).one()
        validations = [session.scalar(crud.select(Job.id).where(Job.submission_id == s))
                       for s in (first.json()["id"], from_ann.json()["id"])]
    order = [job for job in fairest_queued(league.sessions, limit=100_000) if job in {private, *validations}]

    assert (owner, status) == (dora_user.id, "queued")
    assert first.status_code == 201, first.text
    assert (second.status_code, second.json()["detail"]) == (
        429, "1 of your uploads or races are still waiting or running (at most 1 at once): upload again when one "
             "of them is done")
    assert from_ann.status_code == 201
    assert order == [*validations, private]  # hers first: the private test is no job of hers ahead of it
