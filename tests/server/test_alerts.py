"""deploy/prometheus/alerts.yml, tested with Prometheus' own `promtool test rules` against series the
league really exports: the names and labels of each input series are taken from a scrape of a league
whose jobs ran through their leases, so a metric renamed in league/server/metrics.py (or a label
changed) fails here. Each alert is shown to fire when it should, and not before its `for:` is over."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
from datetime import timedelta
from pathlib import Path

import pytest
import yaml
from prometheus_client.parser import text_string_to_metric_families
from sqlalchemy import select

from league.server.db.models import Job, WorkerProcess
from league.server.jobs.handlers import HANDLERS
from league.server.jobs.leases import claim, retry_or_fail
from league.server.supervise import ChildWorker

from league.validation.report import ValidationReport

from ..layout import REPO
from .api.in_process import in_process_league

ALERTS = REPO / "deploy" / "prometheus" / "alerts.yml"

SCRAPE_S = 15  # the input series' step: a scrape every 15 s, as Prometheus' default


@pytest.fixture(scope="module")
def promtool() -> str:
    found = shutil.which("promtool")
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("promtool is missing: the README's test command installs Debian's prometheus package")
        pytest.skip("promtool is not installed (apt-get install prometheus)")
    return found


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict[str, list[dict[str, str]]]:
    """Metric sample name -> the label sets of its samples, from a real league's /metrics after one
    validation passed, one failed for good (an error on every attempt), with one queued and a worker
    registered."""
    tmp_path = tmp_path_factory.mktemp("alerts")
    with in_process_league("sqlite", tmp_path, bootstrap=False, metrics_token="scrape-me") as league:
        student, _ = league.student("mo")
        submission = league.submission(student, status="pending")
        with league.sessions.begin() as session:
            job = session.scalars(select(Job).where(Job.submission_id == submission.id)).one()
            job.max_attempts = 1
            job.enqueued_at -= timedelta(seconds=30)
            session.add(WorkerProcess(host="box-7", pid=4242, version="test"))
        claim(league.sessions, HANDLERS, job_id=job.id, attempt_id="a1")
        retry_or_fail(league.sessions, HANDLERS, job_id=job.id, attempt_id="a1", reason="OSError: disk full")
        passed = league.submission(student, status="pending")
        with league.sessions() as session:
            passing = session.scalar(select(Job.id).where(Job.submission_id == passed.id))
        league.finish_job(passing, ValidationReport(ok=True, error=None, obs_dim=5, log=""))  # queues its evaluation
        league.app.state.supervisor = ChildWorker(threads=None)  # what `league serve` adds (not started here)
        with league.client("scrape-me") as prometheus:
            prometheus.get("/api/health")
            text = prometheus.get("/metrics").text
    samples: dict[str, list[dict[str, str]]] = {}
    for family in text_string_to_metric_families(text):
        for sample in family.samples:
            samples.setdefault(sample.name, []).append(dict(sample.labels))
    return samples


def series(exported: dict[str, list[dict[str, str]]], name: str, **wanted: str) -> str:
    """`name{labels}` of an exported sample whose labels include `wanted`, as promtool writes series."""
    assert name in exported, f"the league exports no {name}: deploy/prometheus/alerts.yml names a series that is gone"
    for labels in exported[name]:
        if wanted.items() <= labels.items():
            return name + "{" + ",".join(f'{key}="{value}"' for key, value in sorted(labels.items())) + "}"
    raise AssertionError(f"no {name} sample with {wanted}: {exported[name]}")


def test_every_series_the_alerts_read_is_exported(exported):
    rules = yaml.safe_load(ALERTS.read_text())["groups"][0]["rules"]
    named = {name for rule in rules for name in re.findall(r"\b(league_[a-z_]+)", rule["expr"])}
    assert named and named <= set(exported), named - set(exported)


def run_promtool(promtool: str, tmp_path: Path, tests: list[dict]) -> subprocess.CompletedProcess:
    spec = tmp_path / "alerts.test.yml"
    spec.write_text(yaml.safe_dump({"rule_files": [str(ALERTS)], "evaluation_interval": "15s", "tests": tests},
                                   sort_keys=False))
    return subprocess.run([promtool, "test", "rules", str(spec)], capture_output=True, text=True, timeout=60)


def at(minutes: float, alerts: list[dict], name: str) -> dict:
    return {"eval_time": f"{int(minutes * 60)}s", "alertname": name, "exp_alerts": alerts}


def fired(name: str, shown_value: str = "") -> dict:
    """The alert as promtool expects it: the rule's labels, and its annotations with the value as the
    rule's template shows it (humanizeDuration, humanizePercentage)."""
    rule = next(r for r in yaml.safe_load(ALERTS.read_text())["groups"][0]["rules"] if r.get("alert") == name)
    annotations = {key: re.sub(r"\{\{[^}]*\}\}", shown_value, text) for key, text in rule["annotations"].items()}
    return {"exp_labels": rule["labels"], "exp_annotations": annotations}


def test_no_worker_alive_is_alerted_on_after_a_minute(promtool, exported, tmp_path):
    """The gauge reads 1 for 5 minutes, then 0 (the worker's heartbeat is older than the silence window,
    or no worker is registered at all): pending at once, firing once `for: 1m` is over."""
    alive = series(exported, "league_workers_alive")
    test = {"interval": f"{SCRAPE_S}s", "input_series": [{"series": alive, "values": "1x20 0x40"}],
            "alert_rule_test": [at(5, [], "LeagueNoWorker"), at(5.75, [], "LeagueNoWorker"),
                                at(6.5, [fired("LeagueNoWorker")], "LeagueNoWorker")]}
    result = run_promtool(promtool, tmp_path, [test])
    assert result.returncode == 0, result.stdout + result.stderr


def test_a_worker_restarted_again_and_again_and_two_releases_at_once_are_alerted_on(promtool, exported, tmp_path):
    restarts = series(exported, "league_worker_restarts_total")
    build = series(exported, "league_build_info")
    older = re.sub(r'version="[^"]*"', 'version="0.1.9"', build).replace('instance="', 'instance="old-')
    steps = 60 * 60 // SCRAPE_S
    test = {"interval": f"{SCRAPE_S}s",
            "input_series": [
                {"series": restarts, "values": f"0x{steps // 2} 1x20 2x20 3x20 4x{steps}"},  # a 4th at 45 min
                {"series": build, "values": f"1x{steps}"},
                {"series": older + "", "values": f"_x8 1x{steps}"}],  # an old API starts 2 minutes in
            "alert_rule_test": [
                at(40, [], "LeagueWorkerRestarting"),
                at(46, [fired("LeagueWorkerRestarting", "4")], "LeagueWorkerRestarting"),
                at(5, [], "LeagueMixedVersions"),
                at(8, [fired("LeagueMixedVersions", "2")], "LeagueMixedVersions")]}
    result = run_promtool(promtool, tmp_path, [test])
    assert result.returncode == 0, result.stdout + result.stderr


def test_a_queue_behind_by_ten_minutes_and_failing_jobs_are_alerted_on(promtool, exported, tmp_path):
    oldest = series(exported, "league_queue_oldest_job_age_seconds")
    failed = series(exported, "league_job_failures_total", reason="error")
    finished = series(exported, "league_job_duration_seconds_count")
    steps = 40 * 60 // SCRAPE_S
    test = {"interval": f"{SCRAPE_S}s",
            "input_series": [
                {"series": oldest, "values": f"0+{SCRAPE_S}x{steps}"},  # nothing is claimed: it ages
                {"series": failed, "values": f"0+3x{steps}"},  # 3 failures a scrape against 2 done: 60 %
                {"series": finished, "values": f"0+2x{steps}"}],
            "alert_rule_test": [
                at(14, [], "LeagueQueueBehind"),  # over 600 s at 10 min, `for: 5m`
                at(16, [fired("LeagueQueueBehind", "16m 0s")], "LeagueQueueBehind"),
                at(4, [], "LeagueJobsFailing"),  # failing from the start, `for: 5m`
                at(7, [fired("LeagueJobsFailing", "60%")], "LeagueJobsFailing")]}
    result = run_promtool(promtool, tmp_path, [test])
    assert result.returncode == 0, result.stdout + result.stderr
