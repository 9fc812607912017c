"""Benchmark of the grades of a course: 200 students, three assignments, every final tested.

    python benchmarks/bench_grades.py [--backend sqlite|postgres] [--students 200] [--repeat 5]

The app in this process (FastAPI's TestClient, no worker) on a new database of the backend. A
course of --students students (every one with an email and a student id), three assignments with
a rubric each (points, points with a rank table, a formula), one final a student in each, frozen
and tested on the private tracks as the due-time pass and a worker leave them (rows written
straight into the database: this measures the grades, not the evaluations), and the bundled
baselines' private tests (their reference lines).

Printed, the median of --repeat requests each: an assignment's grades as JSON and as each file
(generic, Canvas, Moodle), the course's file, beside the path they replace (an assignment's
board as grades, `board.csv`, one line a student).
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import uuid
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path

from fastapi.testclient import TestClient

from _league import database, run_script

RUBRICS = ({"kind": "points", "max_points": 10, "completed": {"kind": "linear", "points": 10}},
           {"kind": "points", "max_points": 10, "completed": {"kind": "steps", "steps": [
               {"completed": 0.5, "points": 3}, {"completed": 0.9, "points": 6}]},
            "rank": {"kind": "table", "points": [4, 3, 2, 1]}},
           {"kind": "formula", "max_points": 10, "formula": "6 * completed + 4 * 0.9 ** (rank - 1)"})


def build(app, students: int) -> tuple[str, list[int]]:
    """The course, its students, assignments, finals and private tests; the instructor's token."""
    from sqlalchemy import select

    from league.server.db import crud
    from league.server.db.models import BASELINE, INSTRUCTOR, READY, STUDENT, StudentAssignment, Submission, User

    due = datetime(2001, 1, 1, tzinfo=timezone.utc)
    with app.state.services.sessions.begin() as session:
        course = crud.first_course(session)
        _, token = crud.create_user(session, name="prof", role=INSTRUCTOR, course=course)
        users = [crud.create_user(session, name=f"student {k:03d}", role=STUDENT, course=course)[0]
                 for k in range(students)]
        for user in users:
            user.email, user.student_id = f"s{user.id}@uni.example", f"S{user.id:05d}"
        assignments = [crud.create_assignment(session, course=course, name=f"assignment {a + 1}", description="",
                                              seed=a, episodes=20, env_options={}, due_at=due + timedelta(days=a))
                       for a in range(3)]
        baselines = list(session.scalars(select(Submission).join(User, User.id == Submission.owner_id)
                                         .where(User.role == BASELINE)))
        for baseline in baselines:
            baseline.status = READY  # as once validated
        for assignment, rubric in zip(assignments, RUBRICS):
            assignment.rubric = rubric
            for k, user in enumerate(users):
                submission, _ = crud.create_submission(session, owner=user, assignment=assignment, name="agent",
                                                       filename="agent.onnx", kind="onnx", max_attempts=1,
                                                       sha256=uuid.uuid4().hex.ljust(64, "0"), size=1, late=k % 7 == 0)
                submission.status = READY
                evaluation = private_test(session, assignment, submission, completed=(k * 7) % 21,
                                          mean_return=k % 13 * 1.5)
                session.add(StudentAssignment(assignment_id=assignment.id, user_id=user.id, final_at=due,
                                              final_submission_id=submission.id, final_evaluation_id=evaluation.id))
            for k, baseline in enumerate(baselines):
                private_test(session, assignment, baseline, completed=10 + k, mean_return=k * 2.0)
        session.flush()
        return token, [a.id for a in assignments]


def private_test(session, assignment, submission, *, completed: int, mean_return: float):
    """A finished private evaluation of 20 episodes, as a worker leaves it (no episode rows)."""
    from league.server.course.results import settings_key
    from league.server.db import crud
    from league.server.db.models import DONE, PRIVATE_TRACKS

    settings = assignment.private_settings()
    evaluation, job = crud.create_evaluation(session, submission=submission, assignment=assignment, settings=settings,
                                             result_key=settings_key(settings), max_attempts=1, track=PRIVATE_TRACKS)
    evaluation.status, evaluation.completed, evaluation.episodes_total = DONE, completed, 20
    evaluation.mean_return, evaluation.mean_steps, evaluation.mean_speed = mean_return, 500.0, 0.3
    job.status = DONE
    return evaluation


def median_ms(client, path: str, repeat: int, **params) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        response = client.get(path, params=params)
        times.append(time.perf_counter() - start)
        response.raise_for_status()
    return 1000 * statistics.median(times)


@dataclass
class GradesFigures:
    backend: str
    students: int
    rows: int  # of an assignment's grades, the baselines' included
    built_s: float  # writing the course
    repeat: int  # requests per figure
    ms: dict[str, float]  # what -> median milliseconds


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite")
    parser.add_argument("--students", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=5)
    return parser.parse_args(argv)


def measure(args: argparse.Namespace) -> GradesFigures:
    from league.server.app import create_app
    from league.server.core.config import Settings
    from league.server.db.session import make_engine, migrate

    with tempfile.TemporaryDirectory() as folder, database(args.backend, Path(folder)) as database_url:
        settings = Settings(_env_file=None, data_dir=Path(folder) / "data", database_url=database_url)
        engine = make_engine(settings.resolved_database_url)
        migrate(engine)
        engine.dispose()
        app = create_app(settings)
        with TestClient(app):
            start = time.perf_counter()
            token, ids = build(app, args.students)
            built = time.perf_counter() - start
            with TestClient(app, headers={"Authorization": f"Bearer {token}"}) as client:
                rows = len(client.get(f"/api/assignments/{ids[2]}/grades").json()["rows"])
                ms = {
                    "an assignment's board as grades (board.csv, before)":
                        median_ms(client, f"/api/assignments/{ids[2]}/board.csv", args.repeat, board="private"),
                    "an assignment's grades, JSON": median_ms(client, f"/api/assignments/{ids[2]}/grades", args.repeat),
                    **{f"an assignment's grades, {fmt} file":
                       median_ms(client, f"/api/assignments/{ids[2]}/grades.csv", args.repeat, format=fmt)
                       for fmt in ("generic", "canvas", "moodle")},
                    "the course's file (3 assignments)": median_ms(client, "/api/grades.csv", args.repeat),
                }
    return GradesFigures(backend=args.backend, students=args.students, rows=rows, built_s=built, repeat=args.repeat,
                         ms=ms)


def report(figures: GradesFigures) -> None:
    f = figures
    print(f"{f.backend}: {f.students} students x 3 assignments ({f.rows} rows an assignment with the "
          f"baselines; built in {f.built_s:.1f} s); median of {f.repeat} requests")
    for name, ms in f.ms.items():
        print(f"  {name:<55} {ms:8.1f} ms")


def main(argv: list[str] | None = None) -> int:
    report(measure(parse(argv)))
    return 0


if __name__ == "__main__":
    run_script(main)
