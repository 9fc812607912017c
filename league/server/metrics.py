"""Prometheus metrics at /metrics (prometheus-client's text format).

What the database holds is read from it at scrape time by `DatabaseCollector`: every API process
answers the same, and the figures of jobs that workers (other processes, other machines) ran need
no multiprocess mode, no shared directory and no push. Durations come from the jobs' own
`started_at`/`finished_at` columns as a histogram computed in SQL, so they survive restarts and
count each job's last (successful) attempt once. Only the API's own request latency is measured in
this process (`RequestLatency`), labelled by route template so that its series stay bounded.

/metrics takes `Authorization: Bearer` with the `metrics_token` setting (what Prometheus is given:
it reads nothing else) or an instructor's token.
"""
from __future__ import annotations

import hmac
import time
from collections.abc import Iterator
from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Request, Response, status
from fastapi.concurrency import run_in_threadpool
from prometheus_client import (
    CONTENT_TYPE_LATEST, CollectorRegistry, Histogram, disable_created_metrics, generate_latest,
)
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, HistogramMetricFamily
from prometheus_client.registry import Collector
from sqlalchemy import Float, case, cast, func, select
from sqlalchemy.orm import Session, sessionmaker
from starlette.routing import Mount

import league
from league.server.api.deps import SessionsDep, SettingsDep
from league.server.core.config import Settings
from league.server.db import crud
from league.server.db.models import (
    DONE, FAILED, INSTRUCTOR, QUEUED, READY, REJECTED, EpisodeResult, Job, Submission, utcnow,
)
from league.server.core.logs import log_access
from league.server.db.session import head_revision
from league.server.jobs import registry
from league.server.jobs.leases import queue_depth

# job durations (seconds): a validation takes seconds, an evaluation of 100 episodes minutes, a race about one
JOB_BUCKETS = (1, 2, 5, 10, 20, 30, 60, 120, 300, 600, 1200, 1800, 3600)
# time in the queue (seconds): under a second when a worker is free, minutes in a deadline rush
WAIT_BUCKETS = (0.5, 1, 2, 5, 10, 30, 60, 120, 300, 600, 1800, 3600)
UNRECORDED = "unrecorded"  # the failure label of jobs that failed before jobs.failure was kept
REQUEST_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30)
UNMATCHED = "unmatched"  # the route label of a path no route serves (bounded: not the raw path)
# the validation of an upload, by the submission's status: what its sandbox made of it
VALIDATION_OUTCOMES = {READY: "ok", REJECTED: "rejected", FAILED: "failed"}

router = APIRouter()


def seconds_between(start, end, dialect: str):
    """end - start in seconds, in SQL (SQLite keeps datetimes as text; PostgreSQL as timestamps)."""
    if dialect == "postgresql":
        return func.extract("epoch", end - start)
    return (func.julianday(end) - func.julianday(start)) * 86400.0


class DatabaseCollector(Collector):
    """The league's figures from its database, read when Prometheus scrapes."""

    def __init__(self, sessions: sessionmaker[Session], silent_after_s: float):
        self.sessions, self.silent_after_s = sessions, silent_after_s

    def collect(self) -> Iterator:
        with self.sessions() as session:
            yield from jobs_by_state(session)
            yield oldest_queued_job(session)
            yield job_durations(session)
            yield job_waits(session)
            yield job_failures(session)
            yield job_retries(session)
            yield validation_outcomes(session)
            yield episode_outcomes(session)
            yield from workers(session, self.silent_after_s)


class ProcessCollector(Collector):
    """This API process's own figures: its build, and the restarts of the worker `league serve` supervises
    (league.server.supervise; none under --no-worker or another server)."""

    def __init__(self, state):
        self.state = state  # the app's: `league serve` sets state.supervisor once the app is built

    def collect(self) -> Iterator:
        build = GaugeMetricFamily("league_build_info", "The version of this API process and the schema revision "
                                  "it needs (always 1)", labels=["version", "schema"])
        build.add_metric([league.__version__, head_revision()], 1)
        yield build
        supervisor = getattr(self.state, "supervisor", None)
        if supervisor is not None:
            restarts = CounterMetricFamily("league_worker_restarts", "Restarts of the worker process `league "
                                           "serve` supervises, after it died")
            restarts.add_metric([], supervisor.restarts)
            yield restarts


def jobs_by_state(session: Session) -> Iterator:
    jobs = GaugeMetricFamily("league_jobs", "Jobs in the database by kind and status", labels=["kind", "status"])
    counts = select(Job.kind, Job.status, func.count()).group_by(Job.kind, Job.status)
    for kind, state, count in session.execute(counts):
        jobs.add_metric([kind, state], count)
    yield jobs


def oldest_queued_job(session: Session) -> GaugeMetricFamily:
    """How long the oldest queued job has waited (0: none waits): the first sign of a queue that is behind
    or of workers that are gone, whatever the queue's length."""
    _, oldest = queue_depth(session, utcnow())
    return GaugeMetricFamily("league_queue_oldest_job_age_seconds", "Age of the oldest queued job (0: none)",
                             value=oldest or 0.0)


def job_durations(session: Session) -> HistogramMetricFamily:
    """Finished jobs' last attempt, claim to completion, by kind (evaluate, race, validate)."""
    return _histogram(session, "league_job_duration_seconds", "Duration of finished jobs, by kind",
                      Job.started_at, Job.finished_at, JOB_BUCKETS, Job.status == DONE)


def job_waits(session: Session) -> HistogramMetricFamily:
    """Started jobs' last wait in the queue, from being queued (or re-queued) to being claimed, by kind."""
    return _histogram(session, "league_job_wait_seconds", "Time jobs waited in the queue before a worker claimed "
                      "them, by kind", Job.enqueued_at, Job.started_at, WAIT_BUCKETS, Job.status != QUEUED)


def _histogram(session: Session, name: str, documentation: str, start, end, bounds: tuple[float, ...],
               *where) -> HistogramMetricFamily:
    """A histogram by job kind of end - start, counted in SQL."""
    seconds = seconds_between(start, end, session.get_bind().dialect.name)
    buckets = [func.sum(case((seconds <= bound, 1), else_=0)) for bound in bounds]
    rows = session.execute(select(Job.kind, func.count(), func.sum(cast(seconds, Float)), *buckets)
                           .where(*where, start.is_not(None), end.is_not(None)).group_by(Job.kind))
    histogram = HistogramMetricFamily(name, documentation, labels=["kind"])
    for kind, count, total, *cumulative in rows:
        histogram.add_metric([kind], [(str(float(b)), int(c or 0)) for b, c in zip(bounds, cumulative)]
                             + [("+Inf", count)], float(total or 0.0))
    return histogram


def job_failures(session: Session) -> CounterMetricFamily:
    """Jobs failed for good, by kind and why (models.FAILURES): an alert on their rate sees a broken worker
    (error, worker_lost) apart from cancellations."""
    failures = CounterMetricFamily("league_job_failures", "Jobs failed for good, by kind and reason",
                                   labels=["kind", "reason"])
    for kind, reason, count in session.execute(select(Job.kind, Job.failure, func.count())
                                               .where(Job.status == FAILED).group_by(Job.kind, Job.failure)):
        failures.add_metric([kind, reason or UNRECORDED], count)
    return failures


def job_retries(session: Session) -> CounterMetricFamily:
    """Attempts after the first, by kind: a job retried after an error, or after its worker died."""
    retries = CounterMetricFamily("league_job_retries", "Job attempts after the first, by kind", labels=["kind"])
    for kind, count in session.execute(select(Job.kind, func.sum(Job.attempts - 1)).where(Job.attempts > 1)
                                       .group_by(Job.kind)):
        retries.add_metric([kind], int(count or 0))
    return retries


def validation_outcomes(session: Session) -> CounterMetricFamily:
    """Uploads by what their validation sandbox decided: ok, rejected (the model's fault) or failed
    (the sandbox or the worker could not run it)."""
    outcomes = CounterMetricFamily("league_validations", "Validated uploads by outcome", labels=["outcome"])
    counts = dict(session.execute(select(Submission.status, func.count()).group_by(Submission.status)).all())
    for state, outcome in VALIDATION_OUTCOMES.items():
        outcomes.add_metric([outcome], counts.get(state, 0))
    return outcomes


def episode_outcomes(session: Session) -> CounterMetricFamily:
    """Evaluation episodes by how they ended: finished, off_road, too_slow, timeout, dnf (the agent's
    sandbox failed: crashed, over its limits)."""
    outcomes = CounterMetricFamily("league_evaluation_episodes", "Evaluation episodes by outcome", labels=["outcome"])
    for outcome, count in session.execute(select(EpisodeResult.outcome, func.count()).group_by(EpisodeResult.outcome)):
        outcomes.add_metric([outcome], count)
    return outcomes


def workers(session: Session, silent_after_s: float) -> Iterator:
    """Each registered worker process (host/pid), idle or not, and its newest heartbeat: a worker whose
    time falls behind has stopped (its row, and so its series, expires after a few silence windows);
    and how many were heard from within the silence window, a series that exists with no worker at
    all (the alert `league_workers_alive < 1`)."""
    beats = GaugeMetricFamily("league_worker_heartbeat_timestamp_seconds",
                              "Newest heartbeat of each worker process (unix time)", labels=["worker"])
    listed = registry.workers(session)
    for worker in sorted(listed, key=lambda worker: (worker.host, worker.pid)):
        beats.add_metric([f"{worker.host}/{worker.pid}"], worker.heartbeat_at.timestamp())
    yield beats
    alive = GaugeMetricFamily("league_workers_alive", "Worker processes heard from within "
                              "LEAGUE_WORKER_SILENT_AFTER_S")
    alive.add_metric([], sum(registry.is_alive(worker, silent_after_s) for worker in listed))
    yield alive


class RequestLatency:
    """ASGI middleware: the API's answer times by method, route template and status, each answer also
    written to the access log (league.server.core.logs.log_access): one measure for both."""

    def __init__(self, app, histogram: Histogram):
        self.app, self.histogram = app, histogram

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        started, answered = time.perf_counter(), {"status": 500}

        async def sending(message):
            if message["type"] == "http.response.start":
                answered["status"] = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, sending)
        finally:
            seconds = time.perf_counter() - started
            self.histogram.labels(scope["method"], route_template(scope), str(answered["status"])).observe(seconds)
            log_access(scope, answered["status"], seconds)


def route_template(scope) -> str:
    """"/api/races/{race_id}" for /api/races/12: the matched route's path (relative to the prefix its
    router was included with, which is the concrete path's leading segments), or UNMATCHED."""
    route = scope.get("route")
    if route is None:
        return UNMATCHED
    if isinstance(route, Mount):  # static files: one label for the mount
        return route.path
    segments = scope["path"].split("/")
    return "/".join(segments[:len(segments) - route.path.count("/")]) + route.path


def install(app, sessions: sessionmaker[Session], silent_after_s: float) -> None:
    """The app's registry (its own: apps in one process do not mix), its collector and middleware."""
    disable_created_metrics()  # no *_created series: Prometheus needs none, and they double the output
    collectors = CollectorRegistry(auto_describe=False)
    collectors.register(DatabaseCollector(sessions, silent_after_s))
    collectors.register(ProcessCollector(app.state))
    latency = Histogram("league_http_request_duration_seconds", "API answer time by method, route template "
                        "and status", ["method", "route", "status"], registry=collectors, buckets=REQUEST_BUCKETS)
    app.state.metrics = collectors
    app.add_middleware(RequestLatency, histogram=latency)
    app.include_router(router)


async def get_registry(request: Request) -> CollectorRegistry:
    """The app's registry (`install`)."""
    return request.app.state.metrics


@router.get("/metrics", response_class=Response, include_in_schema=True, tags=["monitoring"],
            responses={200: {"content": {CONTENT_TYPE_LATEST: {}}}})
async def read_metrics(request: Request, settings: SettingsDep, sessions: SessionsDep,
                       registry: Annotated[CollectorRegistry, Depends(get_registry)]) -> Response:
    """Prometheus metrics (text format): the metrics_token or an instructor's token, as a bearer token."""
    await run_in_threadpool(check_scraper, request.headers.get("authorization", ""), settings, sessions)
    body = await run_in_threadpool(generate_latest, registry)
    return Response(body, media_type=CONTENT_TYPE_LATEST)


def check_scraper(authorization: str, settings: Settings, sessions: sessionmaker[Session]) -> None:
    scheme, _, token = authorization.partition(" ")
    if scheme.lower() != "bearer" or not token:
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "send the metrics_token or an instructor's token: "
                            "Authorization: Bearer TOKEN", headers={"WWW-Authenticate": "Bearer"})
    expected = settings.metrics_token
    secret = expected.get_secret_value() if expected is not None else ""
    if secret and hmac.compare_digest(token.encode(), secret.encode()):
        return
    with sessions() as session:
        user = crud.user_by_token(session, token=token)
    if user is None or not user.active:
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "unknown token: send the metrics_token or an "
                            "instructor's token", headers={"WWW-Authenticate": "Bearer"})
    if user.role != INSTRUCTOR:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only instructors and the metrics_token read the metrics")
