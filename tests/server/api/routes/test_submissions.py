"""Submissions in process (the app on SQLite and on PostgreSQL, no worker): the refusals, the quota,
storage and the status answer, with what the jobs would write put in the database. What a worker
runs (validation and evaluation in real sandboxes): tests/system/api/test_submissions.py."""
from __future__ import annotations

import hashlib
from datetime import datetime, timedelta

import pytest

from league.server.api.deps import UNKNOWN_TOKEN
from league.server.db.models import REJECTED

from ...api_calls import create_student, submission, unique, upload
from ...backends import BACKENDS
from ..in_process import evaluation_outcome, in_process_league


def test_empty_file_is_refused(app_league, tmp_path):
    student = create_student(app_league, unique("empty"))
    empty = tmp_path / "empty.onnx"
    empty.write_bytes(b"")
    response = upload(student, empty)
    assert response.status_code == 400
    assert response.json() == {"detail": "the file is empty"}


def test_an_empty_file_is_said_to_be_empty_even_over_the_quota(app_league, tmp_path):
    user, student = app_league.student("empty-over")
    for _ in range(4):  # LEAGUE_QUOTA_PER_DAY=4: the quota is spent
        app_league.submission(user)
    empty = tmp_path / "empty.onnx"
    empty.write_bytes(b"")
    response = upload(student, empty)
    assert response.status_code == 400
    assert response.json() == {"detail": "the file is empty"}


def test_unknown_file_type_is_refused(app_league, tmp_path):
    student = create_student(app_league, unique("type"))
    script = tmp_path / "agent.py"
    script.write_text("print('hello')")
    response = upload(student, script)
    assert response.status_code == 415
    assert response.json()["detail"] == ("unsupported file type '.py': the league runs ONNX (.onnx) and TorchScript "
                                         "(.pt) files; export the network with torch.onnx.export or torch.jit.script")


def test_a_keras_model_is_refused_with_the_route_to_onnx(app_league, tmp_path):
    student = create_student(app_league, unique("keras"))
    keras_file = tmp_path / "actor.h5"
    keras_file.write_bytes(b"\x89HDF\r\n\x1a\n")
    response = upload(student, keras_file)
    assert response.status_code == 415
    assert response.json()["detail"].startswith("unsupported file type '.h5' (a Keras model): the league runs ONNX "
                                                "(.onnx) and TorchScript (.pt) files; convert it to ONNX first, with "
                                                "tf2onnx or Keras' own model.export(path, format='onnx')")


def test_file_over_the_size_limit_is_refused(app_league, tmp_path):
    student = create_student(app_league, unique("big"))
    big = tmp_path / "big.onnx"
    big.write_bytes(b"\0" * (5 * 1024 * 1024 + 1))
    response = upload(student, big)
    assert response.status_code == 413
    assert response.json() == {"detail": "file too large: the limit is 5 MB"}
    assert student.get("/api/submissions").json() == []


def test_size_limit_holds_for_a_streamed_upload_without_length(app_league):
    """Chunked transfer: no Content-Length to trust, the limit is enforced while reading."""
    student = create_student(app_league, unique("stream"))
    boundary = "leaguetestboundary"

    def body():
        yield (f"--{boundary}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"big.onnx\"\r\n"
               "Content-Type: application/octet-stream\r\n\r\n").encode()
        for _ in range(7):  # 7 MB > 5 MB
            yield b"\1" * (1024 * 1024)
        yield f"\r\n--{boundary}--\r\n".encode()

    response = student.post("/api/submissions", content=body(),
                            headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
    assert response.status_code == 413
    assert student.get("/api/health").json()["database"]  # the app answers (503 "degraded": no worker here)


def test_same_file_twice_is_stored_once(app_league, models):
    student = create_student(app_league, unique("twice"))
    first = upload(student, models["heuristic_onnx"]).json()["id"]
    second = upload(student, models["heuristic_onnx"]).json()["id"]
    one, two = submission(student, first), submission(student, second)
    digest = hashlib.sha256(models["heuristic_onnx"].read_bytes()).hexdigest()
    assert one["sha256"] == two["sha256"] == digest
    stored = list((app_league.settings.data_dir / "blobs").rglob(digest))
    assert len(stored) == 1 and stored[0].read_bytes() == models["heuristic_onnx"].read_bytes()


def test_quota_counts_accepted_uploads_only_and_names_the_next_free_slot(app_league, models):
    user, student = app_league.student("quota")
    app_league.submission(user, status=REJECTED)  # as its validation left it: free
    for _ in range(4):  # LEAGUE_QUOTA_PER_DAY=4; the rejected upload is free
        assert upload(student, models["heuristic_onnx"]).status_code == 201

    response = upload(student, models["heuristic_onnx"])

    assert response.status_code == 429
    detail = response.json()["detail"]
    assert detail.startswith("quota reached: 4 submissions per 24 hours (rejected ones do not count); "
                             "next free slot at ")
    oldest = min(datetime.fromisoformat(s["created_at"]) for s in student.get("/api/submissions").json()
                 if s["status"] != "rejected")
    assert detail.endswith((oldest + timedelta(hours=24)).isoformat(timespec="seconds"))


def test_missing_and_wrong_tokens_are_refused(app_league, models):
    with app_league.client() as anonymous:
        response = upload(anonymous, models["onnx"])
        assert response.status_code == 401
        assert response.json() == {"detail": "missing token: send the header Authorization: Bearer TOKEN"}
    with app_league.client("lg_not-a-real-token") as stranger:
        assert stranger.get("/api/submissions").status_code == 401
        assert stranger.get("/api/submissions").json() == {"detail": UNKNOWN_TOKEN}


@pytest.mark.parametrize("kind", BACKENDS)
def test_a_student_has_a_limited_number_of_jobs_in_flight(kind, tmp_path, models):
    """Uploads beyond LEAGUE_MAX_JOBS_IN_FLIGHT wait their turn: no worker runs here, every job waits."""
    limit = 2
    with in_process_league(kind, tmp_path, max_jobs_in_flight=limit) as league:
        _, student = league.student("busy")
        statuses = [upload(student, models["heuristic_onnx"]) for _ in range(limit)]
        refused = upload(student, models["heuristic_onnx"])
    accepted = [response.status_code for response in statuses]
    assert accepted == [201] * limit
    assert refused.status_code == 429
    assert refused.json() == {"detail": f"{limit} of your uploads or races are still waiting or running (at most "
                                        f"{limit} at once): upload again when one of them is done"}


def test_a_rejected_uploads_file_is_deleted(app_league, tmp_path):
    """Its bytes leave the database when its validation rejects it, and each store's copy with the next sweep."""
    from league.server.db import crud
    from league.server.db.models import Job, Submission
    from league.server.jobs.validate import ValidateSubmission
    from league.validation.report import ValidationReport

    from league import testing as mf

    user, student = app_league.student("reject")
    bad = mf.random_bytes(tmp_path / "random.onnx")
    submission_id = upload(student, bad).json()["id"]
    digest = student.get(f"/api/submissions/{submission_id}").json()["sha256"]
    with app_league.sessions.begin() as session:  # what the worker's validation writes
        job = session.query(Job).filter_by(submission_id=submission_id).one()
        ValidateSubmission().finish(session, job, ValidationReport(False, None, "not an ONNX model", ""))
        assert session.get(Submission, submission_id).status == "rejected"
    with app_league.sessions() as session:
        assert digest not in crud.kept_blobs(session)
    store = app_league.app.state.services.store
    assert store.path(digest).exists()
    store.sweep(set(), older_than_s=0)
    assert not store.path(digest).exists()


def test_the_status_answer_is_small_its_episodes_paged_and_pollers_get_304(app_league):
    """A 100-episode evaluation: the status answer carries its figures and a link, not its episodes,
    and does not grow with them; the link pages through all of them; an unchanged answer is 304."""
    from league.server.course.results import queue_evaluation
    from league.server.db import crud
    from league.server.db.models import Submission

    owner, student = app_league.student("poller")
    ready = app_league.submission(owner, evaluated=False)
    with student:
        before = student.get(f"/api/submissions/{ready.id}")
        assert before.status_code == 200 and before.json()["links"] == {"episodes": None}
        with app_league.sessions.begin() as session:
            job_id = queue_evaluation(session, submission=session.get(Submission, ready.id), max_attempts=1).id
        app_league.finish_job(job_id, evaluation_outcome(60, episodes=100))
        response = student.get(f"/api/submissions/{ready.id}")
        assert response.status_code == 200 and response.headers["cache-control"] == "private, no-cache"
        status = response.json()
        evaluation = status["evaluation"]
        assert (evaluation["status"], evaluation["completed"], evaluation["episodes_total"]) == ("done", 60, 100)
        assert evaluation["log"] == "evaluated in a test" and "episodes" not in evaluation
        assert len(response.content) < len(before.content) + 600  # the figures, not 100 episodes

        etag = response.headers["etag"]
        unchanged = student.get(f"/api/submissions/{ready.id}", headers={"If-None-Match": f'W/{etag}, "other"'})
        assert (unchanged.status_code, unchanged.content, unchanged.headers["etag"]) == (304, b"", etag)
        assert student.patch(f"/api/submissions/{ready.id}", json={"public": True}).status_code == 200
        changed = student.get(f"/api/submissions/{ready.id}", headers={"If-None-Match": etag})
        assert changed.status_code == 200 and changed.json()["public"] is True

        link = status["links"]["episodes"]
        pages = [student.get(link, params={"offset": offset, "limit": 30}).json() for offset in (0, 30, 60, 90)]
        assert [page["total"] for page in pages] == [100] * 4
        assert [len(page["items"]) for page in pages] == [30, 30, 30, 10]
        rows = [row for page in pages for row in page["items"]]
        assert [row["index"] for row in rows] == list(range(100))
        assert [row["outcome"] for row in rows] == ["finished"] * 60 + ["off_road"] * 40
        assert set(rows[0]) == {"index", "seed", "steps", "return", "mean_speed", "outcome", "reason"}
        latest = student.get(f"/api/submissions/{ready.id}/episodes").json()  # default: the latest evaluation
        assert latest["evaluation_id"] == evaluation["id"] and latest["items"] == rows[:100]
        assert student.get(link, params={"limit": 1001}).status_code == 422

        other_owner, other = app_league.student("other")
        theirs = app_league.submission(other_owner)
        with other:
            assert other.get(link).status_code == 404  # not theirs
        foreign = student.get(f"/api/submissions/{ready.id}/episodes",
                              params={"evaluation_id": evaluation["id"] + 10_000})
        assert foreign.status_code == 404 and foreign.json() == {"detail": "no such evaluation of this submission"}
        with app_league.sessions() as session:
            their_evaluation = crud.latest_evaluation(session, submission_id=theirs.id, result_key=None).id
        mixed = student.get(f"/api/submissions/{ready.id}/episodes", params={"evaluation_id": their_evaluation})
        assert mixed.status_code == 404


def same_answer(answer, other) -> bool:
    """Byte for byte, headers (but the date) in order."""
    def head(response):
        return [(name, value) for name, value in response.headers.multi_items() if name != "date"]
    return (answer.status_code, head(answer), answer.content) == (other.status_code, head(other), other.content)


def test_status_answers_skip_the_router_and_answer_as_the_route(app_league):
    """StatusAnswers answers GET /api/submissions/{id} before the router: the same bytes and headers as
    the route (which an id written "02" reaches), 304s included, timed under the route's label and
    logged with the reader's id."""
    import logging

    from prometheus_client import generate_latest

    from league.server.api.routes.submissions import StatusAnswers

    assert any(middleware.cls is StatusAnswers for middleware in app_league.app.user_middleware)
    owner, student = app_league.student("fast poller")
    ready = app_league.submission(owner)
    label = 'method="GET",route="/api/submissions/{submission_id}",status="%d"'
    with student:
        def counted(status: int) -> float:
            for line in generate_latest(app_league.app.state.metrics).decode().splitlines():
                if line.startswith("league_http_request_duration_seconds_count{") and label % status in line:
                    return float(line.rsplit(" ", 1)[1])
            return 0.0

        before = counted(200), counted(304)
        fast, routed = student.get(f"/api/submissions/{ready.id}"), student.get(f"/api/submissions/0{ready.id}")
        assert fast.status_code == 200 and same_answer(fast, routed)
        etag = {"If-None-Match": fast.headers["etag"]}
        fast, routed = (student.get(f"/api/submissions/{ready.id}", headers=etag),
                        student.get(f"/api/submissions/0{ready.id}", headers=etag))
        assert fast.status_code == 304 and same_answer(fast, routed)
        assert (counted(200), counted(304)) == (before[0] + 2, before[1] + 2)

        records = []
        handler = logging.Handler()
        handler.emit = records.append
        access = logging.getLogger("league.server.access")
        access.addHandler(handler)
        level = access.level
        access.setLevel(logging.INFO)
        try:
            assert student.get(f"/api/submissions/{ready.id}").status_code == 200
        finally:
            access.removeHandler(handler)
            access.setLevel(level)
        assert [(record.path, record.status, record.user_id) for record in records] == [
            (f"/api/submissions/{ready.id}", 200, owner.id)]


def shared_fields(detail: dict) -> dict:
    """A status answer without what only it carries (the sandbox logs, the link): the list's item."""
    shown = {name: value for name, value in detail.items() if name not in ("log", "links")}
    if shown["evaluation"] is not None:
        shown["evaluation"] = {name: value for name, value in shown["evaluation"].items() if name != "log"}
    return shown


@pytest.mark.parametrize("kind", BACKENDS)
def test_the_status_answer_agrees_with_the_list_and_refuses_as_every_route(kind, tmp_path):
    """The status answer reads its rows with two statements of its own (crud.status_row); the list reads
    them with the ORM functions every other route uses. Each answer agrees with the list's item, for a
    student's picked, unpicked, unevaluated and rejected uploads, before and after a change of the
    settings (stale results), and for an instructor's view of them and of the baselines; the
    refusals are the token dependency's and the route's."""
    from league.server.db import crud

    with in_process_league(kind, tmp_path) as league:
        owner, student = league.student("lister")
        older, newer = league.submission(owner), league.submission(owner)
        unevaluated, rejected = league.submission(owner, evaluated=False), league.submission(owner, status=REJECTED)
        instructor = league.client(league.instructor_token)

        def agree(client, ids, all_=False):
            listed = {item["id"]: item for item in client.get("/api/submissions", params={"all": all_}).json()}
            for submission_id in ids:
                detail = client.get(f"/api/submissions/{submission_id}")
                assert detail.status_code == 200, detail.text
                assert same_answer(detail, client.get(f"/api/submissions/0{submission_id}"))  # by the route
                assert shared_fields(detail.json()) == listed[submission_id]
                assert detail.json()["links"]["episodes"] == (
                    None if listed[submission_id]["evaluation"] is None else
                    f"/api/submissions/{submission_id}/episodes?evaluation_id="
                    f"{listed[submission_id]['evaluation']['id']}")
            return listed

        mine = [older.id, newer.id, unevaluated.id, rejected.id]
        with student, instructor:
            assert [agree(student, mine)[i]["active"] for i in mine] == [False, False, True, False]  # the latest ready
            assert student.patch(f"/api/submissions/{older.id}", json={"active": True}).status_code == 200
            assert [agree(student, mine)[i]["active"] for i in mine] == [True, False, False, False]
            baselines = [item["id"] for item in instructor.get("/api/submissions", params={"all": True}).json()
                         if item["owner"] == "baselines"]
            assert baselines
            agree(instructor, mine + baselines, all_=True)

            with league.sessions.begin() as session:  # new settings, their re-evaluations not queued yet
                assignment = crud.default_assignment(session, course_id=crud.first_course(session).id)
                assignment.seed += 1
            listed = agree(student, mine)
            assert listed[newer.id]["evaluation"]["stale"] is True
            assert all(item["evaluation"]["stale"] for item in agree(instructor, mine + baselines, all_=True).values()
                       if item["evaluation"] is not None)
            settings = instructor.get("/api/settings/evaluation").json()
            changed = instructor.put("/api/settings/evaluation", json={**settings, "seed": settings["seed"] + 1})
            assert changed.status_code == 200
            listed = agree(student, mine)
            assert listed[newer.id]["evaluation"]["status"] == "queued"  # its re-evaluation, of the new settings
            assert listed[newer.id]["evaluation"]["stale"] is False
            agree(instructor, mine + baselines, all_=True)

            other_owner, other = league.student("other lister")
            with other:
                refused = other.get(f"/api/submissions/{newer.id}")
                assert (refused.status_code, refused.json()) == (404, {"detail": "no such submission"})
                assert other.get(f"/api/submissions/{baselines[0]}").status_code == 404
            assert student.get("/api/submissions/999999").json() == {"detail": "no such submission"}
            with league.client("not a token") as stranger:
                unknown = stranger.get(f"/api/submissions/{newer.id}")
            assert (unknown.status_code, unknown.json()) == (401, {"detail": UNKNOWN_TOKEN})
            assert unknown.headers["www-authenticate"] == "Bearer"
            with league.client() as anonymous:
                missing = anonymous.get(f"/api/submissions/{newer.id}")
            assert missing.status_code == 401 and missing.json()["detail"].startswith("missing token")
            _, elsewhere_token = league.user("elsewhere", role="instructor", course_name=unique("other course"))
            with league.client(elsewhere_token) as elsewhere:
                assert elsewhere.get(f"/api/submissions/{newer.id}").status_code == 404
                assert elsewhere.get(f"/api/submissions/{baselines[0]}").status_code == 200  # every course's
            assert instructor.post(f"/api/users/{owner.id}/revoke").status_code == 200
            revoked = student.get(f"/api/submissions/{newer.id}")
            assert (revoked.status_code, revoked.json()) == (401, {"detail": "this account was revoked"})
