"""Benchmark of a Prometheus scrape of /metrics on a semester's database.

    python benchmarks/bench_metrics.py [--backend sqlite|postgres] [--students 200] [--uploads 600]
                                       [--episodes 100] [--races 200] [--scrapes 20]

/metrics reads its figures from the database at every scrape (league/server/metrics.py): counts of
jobs, submissions and episodes, and the job-duration histogram computed in SQL. This writes a
semester's rows straight into a fresh database (--students students, --uploads submissions each
with its validation and evaluation jobs done and --episodes episodes, --races finished races: the
rows bench_backup.py's semester has, without running the jobs) and times --scrapes scrapes through
the app (FastAPI's TestClient, one after the other), printed beside GET /api/health, the request a
monitor already polls. Medians and ranges, in milliseconds.
"""
from __future__ import annotations

import argparse
import random
import statistics
import tempfile
import time
import uuid
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path

from _league import database, run_script

REQUESTS = (("GET /metrics (a scrape)", "/metrics"), ("GET /api/health", "/api/health"))


def fill(sessions, args) -> None:
    """The semester's rows, as the jobs would have left them (durations drawn like real ones)."""
    from league.server.db import crud
    from league.server.db.models import (
        DONE, EVALUATE, RACE, READY, STUDENT, VALIDATE, EpisodeResult, Evaluation, Job, Race, Submission, utcnow,
    )

    rng, now = random.Random(1), utcnow()
    with sessions.begin() as session:
        course = crud.first_course(session)
        students = [crud.create_user(session, name=f"student{k:03d}", role=STUDENT, course=course)[0]
                    for k in range(args.students)]
        for k in range(args.uploads):
            owner = students[k % len(students)]
            submission = Submission(owner_id=owner.id, name=f"agent{k}", filename="a.onnx", kind="onnx",
                                    sha256=uuid.uuid4().hex * 2, size=1, status=READY, obs_dim=5)
            session.add(submission)
            session.flush()
            evaluation = Evaluation(submission_id=submission.id, course_id=course.id, settings={}, status=DONE,
                                    result_key="k", completed=80, episodes_total=args.episodes, mean_return=1.0)
            session.add(evaluation)
            session.flush()
            for kind, seconds in ((VALIDATE, rng.uniform(2, 8)), (EVALUATE, rng.uniform(30, 300))):
                session.add(Job(kind=kind, owner_id=owner.id, submission_id=submission.id, status=DONE,
                                evaluation_id=evaluation.id if kind == EVALUATE else None,
                                started_at=now - timedelta(seconds=seconds), finished_at=now))
            session.add_all(EpisodeResult(evaluation_id=evaluation.id, index=i, seed=i, steps=500, episode_return=1.0,
                                          mean_speed=0.3, outcome=rng.choice(("finished",) * 4 + ("off_road",)))
                            for i in range(args.episodes))
        for k in range(args.races):
            race = Race(course_id=course.id, seed=k, entrants=[], status=DONE, classification=[])
            session.add(race)
            session.flush()
            session.add(Job(kind=RACE, race_id=race.id, status=DONE, started_at=now - timedelta(seconds=60),
                            finished_at=now))


def timed(client, path: str, token: str, repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        begin = time.perf_counter()
        response = client.get(path, headers={"Authorization": f"Bearer {token}"})
        times.append((time.perf_counter() - begin) * 1000)
        # /api/health: 503 "degraded" here, where no worker runs; its answer is what is timed
        assert response.status_code == 200 or (path == "/api/health" and response.json()["status"] == "degraded"), \
            response.text
    return times


@dataclass
class MetricsFigures:
    backend: str
    students: int
    submissions: int
    episodes: int
    jobs: int
    written_s: float  # writing the semester's rows
    scrapes: int  # requests timed of each kind
    ms: dict[str, list[float]]  # request label -> each request's milliseconds


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite")
    parser.add_argument("--students", type=int, default=200)
    parser.add_argument("--uploads", type=int, default=600)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--races", type=int, default=200)
    parser.add_argument("--scrapes", type=int, default=20)
    return parser.parse_args(argv)


def measure(args: argparse.Namespace) -> MetricsFigures:
    from fastapi.testclient import TestClient

    from league.server.app import create_app
    from league.server.core.config import Settings
    from league.server.db.session import make_engine, migrate

    with tempfile.TemporaryDirectory() as folder, database(args.backend, Path(folder)) as database_url:
        settings = Settings(_env_file=None, data_dir=Path(folder) / "data", database_url=database_url,
                            bootstrap=False, metrics_token="bench")
        engine = make_engine(settings.resolved_database_url)
        migrate(engine)
        engine.dispose()
        app = create_app(settings)
        with TestClient(app) as client:
            begin = time.perf_counter()
            fill(app.state.services.sessions, args)
            written = time.perf_counter() - begin
            timed(client, "/metrics", "bench", 2)  # warm: the first queries' plans and caches
            ms = {label: timed(client, path, "bench", args.scrapes) for label, path in REQUESTS}
    return MetricsFigures(backend=args.backend, students=args.students, submissions=args.uploads,
                          episodes=args.uploads * args.episodes, jobs=2 * args.uploads + args.races,
                          written_s=written, scrapes=args.scrapes, ms=ms)


def report(figures: MetricsFigures) -> None:
    f = figures
    print(f"{f.backend}: {f.students} students, {f.submissions} submissions, {f.episodes} episodes, {f.jobs} jobs "
          f"(written in {f.written_s:.0f} s)")
    for label, times in f.ms.items():
        print(f"  {label:<26} median {statistics.median(times):6.1f} ms  "
              f"(range {min(times):.1f}-{max(times):.1f}, {f.scrapes} requests)", flush=True)


def main(argv: list[str] | None = None) -> int:
    report(measure(parse(argv)))
    return 0


if __name__ == "__main__":
    run_script(main)
