"""Jobs for instructors, in process: their course's jobs only, and cancelling one."""
from __future__ import annotations

from ...api_calls import upload


def test_an_instructor_sees_and_cancels_the_jobs_of_their_course_only(app_league, models):
    _, student = app_league.student("ivan")
    submission_id = upload(student, models["heuristic_onnx"]).json()["id"]  # its validation job waits: no worker
    _, elsewhere = app_league.user("prof", role="instructor", course_name="another course")
    with app_league.client(app_league.instructor_token) as instructor, app_league.client(elsewhere) as stranger:
        job = next(j for j in instructor.get("/api/jobs").json() if j["submission_id"] == submission_id)
        assert job["status"] == "queued"
        assert submission_id not in [j["submission_id"] for j in stranger.get("/api/jobs").json()]
        assert stranger.post(f"/api/jobs/{job['id']}/cancel").status_code == 404
        assert student.post(f"/api/jobs/{job['id']}/cancel").status_code == 403

        cancelled = instructor.post(f"/api/jobs/{job['id']}/cancel")
        again = instructor.post(f"/api/jobs/{job['id']}/cancel")
        me = instructor.get("/api/users/me").json()["name"]
    assert cancelled.status_code == 200, cancelled.text
    assert (cancelled.json()["status"], cancelled.json()["error"]) == ("failed", f"cancelled by {me}")
    assert again.status_code == 409
    assert again.json() == {"detail": f"job {job['id']} is already over"}
    shown = student.get(f"/api/submissions/{submission_id}").json()
    assert (shown["status"], shown["error"]) == ("failed", f"the validation could not be completed: cancelled by {me}")


def test_ids_beyond_64_bits_are_refused_not_a_server_error(app_league):
    huge = 2**63
    with app_league.client(app_league.instructor_token) as instructor:
        responses = [instructor.get(f"/api/submissions/{huge}"), instructor.get(f"/api/races/{huge}"),
                     instructor.get(f"/api/championships/{huge}"), instructor.post(f"/api/jobs/{huge}/cancel"),
                     instructor.post(f"/api/users/{huge}/token"), instructor.get("/api/races", params={
                         "championship_id": huge}),
                     instructor.post("/api/races", json={"submission_ids": [1, huge]})]
    assert [r.status_code for r in responses] == [422] * len(responses), [r.text for r in responses]
