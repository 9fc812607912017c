"""The course leaderboard's rows, computed from a real database (both backends), no server."""
from __future__ import annotations

from league.server.course.results import settings_key
from league.server.course.standings import leaderboard_rows
from league.server.db import crud
from league.server.db.models import BASELINE, DONE, READY, STUDENT, Assignment
from league.server.db.session import make_engine, make_sessionmaker, migrate


def add_evaluated(session, owner, name: str, completed: int) -> int:
    submission, _ = crud.create_submission(session, owner=owner, name=name, filename=f"{name}.onnx", kind="onnx",
                                           sha256=name.ljust(64, "0"), size=1, max_attempts=1)
    submission.status = READY
    settings = {"seed": 0, "episodes": 10, "env_options": {}}
    evaluation, _ = crud.create_evaluation(session, submission=submission,
                                           assignment=session.get(Assignment, submission.assignment_id),
                                           settings=settings,
                                           result_key=settings_key(settings), max_attempts=1)
    evaluation.status, evaluation.completed, evaluation.episodes_total = DONE, completed, 10
    evaluation.mean_return, evaluation.mean_steps, evaluation.mean_speed = float(completed), 500.0, 0.3
    session.flush()
    return submission.id


def test_students_whose_user_id_equals_a_baseline_submission_id_all_have_a_row(backend):
    """As on a fresh install: the baselines' submissions are 1, 2, 3..., and so are the first
    students' user ids. Every student and every baseline keeps its own row."""
    _, database_url = backend
    engine = make_engine(database_url)
    migrate(engine)
    try:
        with make_sessionmaker(engine).begin() as session:
            course = crud.get_or_create_course(session, name="default",
                                               evaluation={"seed": 0, "episodes": 10, "env_options": {}})
            baselines, _ = crud.create_user(session, name="baselines", role=BASELINE, course=None, with_token=False)
            baseline_ids = [add_evaluated(session, baselines, f"baseline{i}", completed=5) for i in range(4)]
            students = [crud.create_user(session, name=f"student{i}", role=STUDENT, course=course)[0]
                        for i in range(4)]
            collisions = {s.id for s in students} & set(baseline_ids)
            assert len(collisions) >= 2, "the test must create colliding ids"
            student_ids = [add_evaluated(session, s, f"agent{i}", completed=9 - i) for i, s in enumerate(students)]
            rows = leaderboard_rows(session, course_id=course.id)
    finally:
        engine.dispose()
    assert sorted(row["submission_id"] for row in rows) == sorted(baseline_ids + student_ids)
    assert [row["owner"] for row in rows[:4]] == ["student0", "student1", "student2", "student3"]
    assert [row["rank"] for row in rows] == list(range(1, 9))
