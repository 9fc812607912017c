"""A worker that is watched: `league serve` restarts its worker process when it dies (logged, counted at
/metrics), /api/health is "degraded" (503) while no worker beats, queue or no queue, and a killed
worker's row (and its metric series) expires."""
from __future__ import annotations

import os
import signal
import time

import httpx
from prometheus_client.parser import text_string_to_metric_families

from ..server.api_calls import TERMINAL, create_student, submission, upload, wait_for
from ..server.backends import fresh_backend
from .servers import embedded_worker, freeze, make_server

SILENT_AFTER_S = 3  # the test server's LEAGUE_WORKER_SILENT_AFTER_S (its workers beat every 0.5 s)


def scrape(url: str) -> dict[str, dict[tuple, float]]:
    response = httpx.get(f"{url}/metrics", headers={"Authorization": "Bearer scrape-me"}, timeout=30)
    assert response.status_code == 200, response.text
    return {sample.name: {**{}, **{tuple(sorted(s.labels.items())): s.value for s in family.samples
                                   if s.name == sample.name}}
            for family in text_string_to_metric_families(response.text) for sample in family.samples}


def test_serve_restarts_its_dead_worker_and_health_says_when_no_worker_beats(tmp_path, models):
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url, LEAGUE_WORKER_SILENT_AFTER_S=str(SILENT_AFTER_S),
                             LEAGUE_BOOTSTRAP="false", LEAGUE_METRICS_TOKEN="scrape-me")
        server.start_api()  # waits for "ok": its worker beats
        try:
            def health() -> httpx.Response:
                return httpx.get(f"{server.url}/api/health", timeout=10)

            first = embedded_worker(server.api)
            freeze(first)  # hung: alive, so not restarted, but silent
            silent = wait_for(health, lambda answer: answer.json()["status"] == "degraded", timeout=60).json()
            assert (health().status_code, silent["queued_jobs"]) == (503, 0)  # no job waits: degraded all the same
            assert [(worker["pid"], worker["alive"]) for worker in silent["workers"]] == [(first, False)]
            assert silent["reason"].startswith(f"no worker heard from in the last {SILENT_AFTER_S} s (no job queued")

            student = create_student(server, "ann")
            os.kill(first, signal.SIGKILL)
            killed = time.monotonic()
            uploaded = upload(student, models["onnx"])  # its validation waits for the next worker
            assert uploaded.status_code == 201, uploaded.text
            with server.client(server.instructor_token) as instructor:
                wait_for(lambda: instructor.get("/api/jobs").json(),
                         lambda jobs: any(job["started_at"] for job in jobs), timeout=120, interval=0.05)
            restart_s = time.monotonic() - killed
            print(f"\nworker restart: a job ran {restart_s:.1f} s after serve's worker was killed (target <= 10 s)")
            validated = wait_for(lambda: submission(student, uploaded.json()["id"]),
                                 lambda value: value["status"] in TERMINAL, timeout=120)
            assert validated["status"] == "ready", validated
            second = embedded_worker(server.api)
            assert second != first
            log = (server.data_dir / "api.log").read_text()
            assert f"serve: worker process {first} was killed by SIGKILL after" in log
            assert f"serve: worker process {second} started (restart 1)" in log
            assert scrape(server.url)["league_worker_restarts_total"] == {(): 1.0}

            # the killed worker's row expires two silence windows after its last beat: its series go
            expired = wait_for(health, lambda answer: [w["pid"] for w in answer.json()["workers"]] == [second],
                               timeout=60).json()
            assert (expired["status"], expired["workers"][0]["alive"]) == ("ok", True)
            samples = scrape(server.url)
            assert [dict(labels)["worker"].rpartition("/")[2]
                    for labels in samples["league_worker_heartbeat_timestamp_seconds"]] == [str(second)]
            assert samples["league_workers_alive"] == {(): 1.0}
        finally:
            server.stop_all()
