"""Log lines (league/server/core/logs.py): with log_format=json and a log_file every line the server and its
worker write is one JSON object with a timestamp, uvicorn's included, the API's in the file and the
worker's in its own beside it; each answer has an access line with its status, latency and user; job
lines carry the job, submission, user, outcome and duration; a refused upload is logged with the user,
the reason and the size; no token. The same run's /metrics hold what its worker left in the database."""
from __future__ import annotations

import json

import pytest
from prometheus_client.parser import text_string_to_metric_families
from sqlalchemy import func, select

from league import testing as mf
from league.server.db.models import Job
from league.server.db.session import make_engine

from ..server.api_calls import create_student, upload, wait_settled
from ..server.backends import fresh_backend
from .servers import make_server


def test_json_lines_from_the_api_uvicorn_and_the_worker(tmp_path):
    with fresh_backend("sqlite", tmp_path) as database_url:
        log_file = tmp_path / "logs" / "league.log"
        server = make_server(tmp_path, database_url, LEAGUE_LOG_FORMAT="json", LEAGUE_LOG_FILE=str(log_file),
                             LEAGUE_BOOTSTRAP="false",
                             LEAGUE_EVAL_EPISODES="1", LEAGUE_EVAL_ENV_OPTIONS='{"max_episode_steps": 50}')
        server.start_api()
        try:
            student = create_student(server, "lou")
            token = student.headers["authorization"].removeprefix("Bearer ")
            refused = student.post("/api/submissions", files={"file": ("model.h5", b"keras")})
            uploaded = upload(student, mf.onnx_heuristic(tmp_path / "lou.onnx"))
            settled = wait_settled(student, uploaded.json()["id"])
            user_id = student.get("/api/users/me").json()["id"]
            with server.client(server.instructor_token) as instructor:  # the jobs' figures, as workers left them
                metrics = instructor.get("/metrics").text
            engine = make_engine(server.env["LEAGUE_DATABASE_URL"])
            with engine.connect() as connection:
                job_counts = connection.execute(select(Job.kind, Job.status, func.count())
                                                .group_by(Job.kind, Job.status)).all()
            engine.dispose()
        finally:
            server.stop_all()
        api_text, worker_text = log_file.read_text(), (tmp_path / "logs" / "league-worker.log").read_text()
        text = api_text + worker_text
    assert refused.status_code == 415 and settled["status"] == "ready"
    api_lines = [json.loads(line) for line in api_text.splitlines() if line.strip()]  # each one JSON, or this fails
    worker_lines = [json.loads(line) for line in worker_text.splitlines() if line.strip()]
    lines = api_lines + worker_lines
    assert all({"at", "level", "logger", "message"} <= set(line) for line in lines)
    assert any(line["logger"] == "uvicorn.error" for line in api_lines)  # "Uvicorn running on ..."
    assert not any(line["logger"] == "uvicorn.access" for line in lines)  # ours say more
    accesses = [line for line in api_lines if line["logger"] == "league.server.access"]
    assert {(a["method"], a["path"], a["status"], a["user_id"]) for a in accesses} >= {
        ("POST", "/api/submissions", 415, user_id), ("POST", "/api/submissions", 201, user_id),
        ("GET", "/api/users/me", 200, user_id), ("GET", "/api/health", 200, None)}
    assert all(a["duration_ms"] > 0 and a["client"] == "127.0.0.1" for a in accesses)
    assert {line["logger"] for line in worker_lines} >= {"league.server.jobs"}
    assert not any(line["logger"].startswith("uvicorn") for line in worker_lines)
    jobs = {line["kind"]: line for line in lines if line.get("job_id") and line.get("submission_id") == settled["id"]}
    assert set(jobs) == {"validate", "evaluate"}
    for kind, outcome in (("validate", "ok"), ("evaluate", "done")):
        assert jobs[kind]["user_id"] == user_id and jobs[kind]["outcome"] == outcome
        assert jobs[kind]["duration_s"] > 0
    refusals = [line for line in lines if line["logger"] == "league.server.uploads"]
    assert [(r["user_id"], r["size"]) for r in refusals] == [(user_id, 5)]
    assert "unsupported file type" in refusals[0]["reason"]
    assert token not in text and server.instructor_token not in text

    samples = {(s.name, tuple(sorted(s.labels.items()))): s.value
               for family in text_string_to_metric_families(metrics) for s in family.samples}
    assert {labels: n for (name, labels), n in samples.items() if name == "league_jobs"} == \
        {(("kind", k), ("status", st)): n for k, st, n in job_counts}
    assert samples[("league_job_duration_seconds_count", (("kind", "validate"),))] == 1
    assert samples[("league_job_duration_seconds_count", (("kind", "evaluate"),))] == 1
    assert samples[("league_job_duration_seconds_sum", (("kind", "evaluate"),))] == \
        pytest.approx(jobs["evaluate"]["duration_s"], rel=0.5, abs=1.0)  # the job line's own measure
    assert samples[("league_validations_total", (("outcome", "ok"),))] == 1
