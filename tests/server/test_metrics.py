"""/metrics: parsed with Prometheus' own text parser, every figure equal to what the database holds
after jobs ran through their leases (in process, on both backends); who may scrape; API latency
labelled by route template, not by the raw path."""
from __future__ import annotations

import os
import socket
from datetime import timedelta

import pytest
from prometheus_client.parser import text_string_to_metric_families
from sqlalchemy import func, select, update

import league as league_package
from league.server.core.clock import utcnow
from league.server.db.models import DONE, EpisodeResult, Job, Submission, WorkerProcess
from league.server.db.session import head_revision
from league.server.jobs import registry
from league.server.jobs.handlers import HANDLERS
from league.server.jobs.leases import claim
from league.server.metrics import JOB_BUCKETS
from league.validation.report import ValidationReport

from .api.in_process import evaluation_outcome, in_process_league
from .backends import BACKENDS


def scrape(client) -> dict[str, dict[tuple, float]]:
    """name -> {sorted label items: value}, for every sample."""
    response = client.get("/metrics")
    assert response.status_code == 200, response.text
    samples: dict[str, dict[tuple, float]] = {}
    for family in text_string_to_metric_families(response.text):
        for sample in family.samples:
            samples.setdefault(sample.name, {})[tuple(sorted(sample.labels.items()))] = sample.value
    return samples


def run_validation(league, job_id: int, ok: bool) -> None:
    report = ValidationReport(ok=ok, error=None if ok else "the model returned NaN or infinite actions",
                              obs_dim=5 if ok else None, log="")
    league.finish_job(job_id, report)


@pytest.mark.parametrize("kind", BACKENDS)
def test_metrics_equal_the_database_after_jobs_ran(kind, tmp_path):
    with in_process_league(kind, tmp_path, bootstrap=False, metrics_token="scrape-me") as league:
        student, _ = league.student("mo")
        good, bad, waiting = (league.submission(student, status="pending") for _ in range(3))
        with league.sessions() as session:
            validation = {s.id: session.scalar(select(Job.id).where(Job.submission_id == s.id)) for s in
                          (good, bad, waiting)}
        run_validation(league, validation[good.id], ok=True)  # queues its evaluation
        run_validation(league, validation[bad.id], ok=False)
        with league.sessions() as session:
            evaluation = session.scalar(select(Job.id).where(Job.submission_id == good.id, Job.kind == "evaluate",
                                                             Job.status == "queued"))
        league.finish_job(evaluation, evaluation_outcome(completed=2, episodes=3))
        assert claim(league.sessions, HANDLERS, job_id=validation[waiting.id], attempt_id="box-7/4242/ab12cd34")
        with league.sessions.begin() as session:  # durations across the buckets (the jobs above took ms)
            finished = session.scalars(select(Job).where(Job.status == DONE).order_by(Job.id)).all()
            for job, seconds in zip(finished, (3.5, 700.25, 45.0)):
                job.started_at = job.finished_at - timedelta(seconds=seconds)

        with league.sessions.begin() as session:  # a worker's row, as it writes it at start
            session.add(WorkerProcess(host="box-7", pid=4242, version="0.1.0"))
        with league.client("scrape-me") as prometheus:
            prometheus.get("/api/races/987654")  # a 404 through a templated route
            samples = scrape(prometheus)
        with league.sessions() as session:
            jobs = session.execute(select(Job.kind, Job.status, func.count()).group_by(Job.kind, Job.status)).all()
            done = session.execute(select(Job.kind, Job.started_at, Job.finished_at).where(Job.status == DONE)).all()
            statuses = dict(session.execute(select(Submission.status, func.count()).group_by(Submission.status)).all())
            episodes = dict(session.execute(select(EpisodeResult.outcome, func.count())
                                            .group_by(EpisodeResult.outcome)).all())
            beat = session.scalars(select(WorkerProcess.heartbeat_at).where(WorkerProcess.kind == "worker")).one()

    assert samples["league_jobs"] == {(("kind", k), ("status", s)): n for k, s, n in jobs}
    durations = {}
    for job_kind, started, finished in done:
        durations.setdefault(job_kind, []).append((finished - started).total_seconds())
    assert sorted(s for seconds in durations.values() for s in seconds) == [3.5, 45.0, 700.25]
    assert {dict(labels)["kind"] for labels in samples["league_job_duration_seconds_count"]} == set(durations)
    for job_kind, seconds in durations.items():
        assert samples["league_job_duration_seconds_count"][(("kind", job_kind),)] == len(seconds)
        assert (samples["league_job_duration_seconds_sum"][(("kind", job_kind),)]
                == pytest.approx(sum(seconds), abs=1e-3))
        for bound in JOB_BUCKETS:
            assert samples["league_job_duration_seconds_bucket"][(("kind", job_kind), ("le", str(float(bound))))] == \
                sum(s <= bound for s in seconds)
    assert samples["league_validations_total"] == {
        (("outcome", "ok"),): statuses.get("ready", 0), (("outcome", "rejected"),): statuses.get("rejected", 0),
        (("outcome", "failed"),): statuses.get("failed", 0)}
    assert statuses.get("rejected") == 1 and statuses.get("ready", 0) >= 1
    assert samples["league_evaluation_episodes_total"] == {(("outcome", o),): n for o, n in episodes.items()}
    assert samples["league_worker_heartbeat_timestamp_seconds"] == {(("worker", "box-7/4242"),): beat.timestamp()}
    assert samples["league_workers_alive"] == {(): 1}  # (the API process's own row is no worker)
    assert samples["league_build_info"] == {(("schema", head_revision()), ("version", league_package.__version__)): 1}
    assert "league_worker_restarts_total" not in samples  # this API process supervises no worker
    routes = {dict(labels)["route"] for labels in samples["league_http_request_duration_seconds_count"]}
    assert "/api/races/{race_id}" in routes and not any("987654" in route for route in routes)


def test_only_the_metrics_token_and_instructors_scrape(tmp_path):
    with in_process_league("sqlite", tmp_path, bootstrap=False, metrics_token="scrape-me") as league:
        _, student = league.student()
        with league.client() as anonymous, league.client("wrong") as stranger, \
                league.client(league.instructor_token) as instructor:
            answers = [anonymous.get("/metrics"), stranger.get("/metrics"), student.get("/metrics"),
                       instructor.get("/metrics")]
    assert [a.status_code for a in answers] == [401, 401, 403, 200]
    assert answers[0].headers["www-authenticate"] == "Bearer"


@pytest.mark.parametrize("kind", BACKENDS)
def test_queue_waits_failures_by_reason_and_retries_equal_the_database(kind, tmp_path):
    """What an administrator asks first: how old is the oldest queued job, how long do jobs wait, what
    failed and why, how often a job was tried again; each through the leases' own paths."""
    from league.server.jobs.leases import cancel, fail, reap, retry_or_fail

    with in_process_league(kind, tmp_path, bootstrap=False, metrics_token="scrape-me") as league:
        student, _ = league.student("mo")
        jobs = []
        for _ in range(5):
            submission = league.submission(student, status="pending")
            with league.sessions() as session:
                jobs.append(session.scalar(select(Job.id).where(Job.submission_id == submission.id)))
        error, impossible, cancelled, lost, waiting = jobs
        with league.sessions.begin() as session:  # one attempt each at most, so a failed attempt is the last
            for job in session.scalars(select(Job).where(Job.id.in_(jobs))):
                job.max_attempts = 2
            session.get(Job, waiting).enqueued_at -= timedelta(seconds=90)
        for attempt in ("a1", "a2"):  # an error, retried once, then failed for good
            claim(league.sessions, HANDLERS, job_id=error, attempt_id=attempt)
            retry_or_fail(league.sessions, HANDLERS, job_id=error, attempt_id=attempt, reason="OSError: disk full")
        claim(league.sessions, HANDLERS, job_id=impossible, attempt_id="b1")
        fail(league.sessions, HANDLERS, job_id=impossible, attempt_id="b1", reason="the model file is gone")
        cancel(league.sessions, HANDLERS, job_id=cancelled, reason="cancelled by the instructor")
        for attempt in ("c1", "c2"):  # its worker dies twice
            claim(league.sessions, HANDLERS, job_id=lost, attempt_id=attempt)
            with league.sessions.begin() as session:
                session.get(Job, lost).heartbeat_at -= timedelta(seconds=600)
            reap(league.sessions, HANDLERS, lease_timeout_s=60)
        with league.client("scrape-me") as prometheus:
            samples = scrape(prometheus)
        with league.sessions() as session:
            failures = session.execute(select(Job.id, Job.failure).where(Job.status == "failed")).all()
            retried = session.scalar(select(func.sum(Job.attempts - 1)).where(Job.attempts > 1))
            started = session.scalar(select(func.count()).where(Job.started_at.is_not(None), Job.status != "queued"))

    assert dict(failures) == {error: "error", impossible: "cannot_succeed", cancelled: "cancelled",
                              lost: "worker_lost"}
    assert samples["league_job_failures_total"] == {
        (("kind", "validate"), ("reason", reason)): 1 for reason in ("error", "cannot_succeed", "cancelled",
                                                                      "worker_lost")}
    assert retried == 2 and samples["league_job_retries_total"] == {(("kind", "validate"),): 2}
    assert samples["league_queue_oldest_job_age_seconds"][()] >= 90
    assert samples["league_job_wait_seconds_count"][(("kind", "validate"),)] == started


def test_the_oldest_queued_job_is_zero_when_none_waits(tmp_path):
    with in_process_league("sqlite", tmp_path, bootstrap=False, metrics_token="scrape-me") as league:
        with league.client("scrape-me") as prometheus:
            assert scrape(prometheus)["league_queue_oldest_job_age_seconds"] == {(): 0.0}


def test_the_workers_alive_gauge_exists_with_no_worker_and_a_dead_workers_series_expires(tmp_path):
    """`league_workers_alive < 1` fires with no worker at all (a worker stopped cleanly removes its row, so
    `time() - max(league_worker_heartbeat_timestamp_seconds)` has no series then); a worker killed with -9
    keeps its series until its row expires, two silence windows after its last heartbeat."""
    with in_process_league("sqlite", tmp_path, bootstrap=False, metrics_token="scrape-me") as league, \
            league.client("scrape-me") as prometheus:
        samples = scrape(prometheus)
        assert samples["league_workers_alive"] == {(): 0}
        assert "league_worker_heartbeat_timestamp_seconds" not in samples
        killed = registry.register(league.sessions)
        assert scrape(prometheus)["league_workers_alive"] == {(): 1}
        with league.sessions.begin() as session:  # killed -9: no more beats
            session.execute(update(WorkerProcess).where(WorkerProcess.id == killed)
                            .values(heartbeat_at=utcnow() - timedelta(seconds=31)))
        samples = scrape(prometheus)
        assert samples["league_workers_alive"] == {(): 0}
        assert len(samples["league_worker_heartbeat_timestamp_seconds"]) == 1  # silent, not yet expired
        with league.sessions.begin() as session:
            session.execute(update(WorkerProcess).where(WorkerProcess.id == killed)
                            .values(heartbeat_at=utcnow() - timedelta(seconds=61)))
        other = registry.register(league.sessions)
        registry.beat(league.sessions, other, league.settings.worker_silent_after_s)  # any process's beat expires it
        samples = scrape(prometheus)
    assert samples["league_workers_alive"] == {(): 1}
    assert [dict(labels)["worker"] for labels in samples["league_worker_heartbeat_timestamp_seconds"]] == \
        [f"{socket.gethostname()}/{os.getpid()}"]  # the one left, `other`
