"""The in-process tier of the API tests: the app itself (FastAPI's TestClient), on a real database
of each backend, with no worker. For every answer that needs no job to run (validation, 4xx,
permissions, quotas); submissions and evaluations a test needs are written to the database as
the jobs would write them; `every_get` lists every GET path the app serves. What needs real
processes (jobs run by a worker in sandboxes, kill -9) is a system test: tests/system/api/.
"""
from __future__ import annotations

import contextlib
import itertools
import re
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from fastapi.testclient import TestClient

from league.server.app import create_app
from league.server.core.config import Settings
from league.server.course.results import settings_key
from league.server.db import crud
from league.server.db.models import DONE, INSTRUCTOR, READY, REJECTED, STUDENT, Submission, User
from league.server.db.session import make_engine, make_sessionmaker, migrate

from ..api_calls import unique
from ..backends import TEST_SETTINGS, fresh_backend


# the pages (not in the API's schema) that every_get reads too
PAGES = ["/", "/login", "/submissions", "/races/{race_id}", "/replay", "/instructor", "/openapi.json"]


def every_get(app, ids: dict[str, list]) -> list[str]:
    """Every GET path of the API (its OpenAPI schema) and the pages, with each combination of the
    ids given for its path parameters."""
    paths = []
    for template in [*(path for path, methods in app.openapi()["paths"].items() if "get" in methods), *PAGES]:
        names = re.findall(r"{(\w+)}", template)
        missing = set(names) - set(ids)
        assert not missing, f"{template}: which {', '.join(sorted(missing))} should this test read? add it to ids"
        for values in itertools.product(*(ids[name] for name in names)):
            paths.append(template.format(**dict(zip(names, values))))
    return paths



class Client(TestClient):
    """A client of the app whose `with` block only closes it: the fixture ran the app's lifespan once."""

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


@dataclass
class InProcessLeague:
    """The app in this process, and ways to put what a test needs straight into its database."""

    app: object
    settings: Settings
    instructor_token: str

    @property
    def sessions(self):
        return self.app.state.services.sessions

    def client(self, token: str | None = None) -> Client:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return Client(self.app, headers=headers)

    def user(self, name: str, role: str = STUDENT, course_name: str | None = None) -> tuple[User, str]:
        """A new user (of the default course, or of a new course) and their token."""
        with self.sessions.begin() as session:
            course = crud.get_or_create_course(session, name=course_name or crud.DEFAULT_COURSE,
                                               evaluation=self.settings.default_evaluation())
            return crud.create_user(session, name=unique(name), role=role, course=course)

    def student(self, name: str = "student") -> tuple[User, Client]:
        user, token = self.user(name)
        return user, self.client(token)

    def submission(self, owner: User, *, status: str = READY, evaluated: bool = True, completed: int = 2,
                   public: bool = False) -> Submission:
        """A submission as its jobs leave it: ready with a finished evaluation, or rejected."""
        with self.sessions.begin() as session:
            digest, owner = uuid.uuid4().hex.ljust(64, "0"), session.get(User, owner.id)
            assignment = crud.default_assignment(session, course_id=(owner.course or crud.first_course(session)).id)
            submission, _ = crud.create_submission(session, owner=owner, assignment=assignment, name=unique("agent"),
                                                   filename="agent.onnx", kind="onnx", sha256=digest, size=1,
                                                   max_attempts=1)
            submission.status, submission.public, submission.obs_dim = status, public, 5
            if status == REJECTED:
                submission.error = "the model returned NaN or infinite actions"
            if status == READY and evaluated:
                settings = self.settings.default_evaluation()
                evaluation, _ = crud.create_evaluation(session, submission=submission, assignment=assignment,
                                                       settings=settings, result_key=settings_key(settings),
                                                       max_attempts=1)
                evaluation.status, evaluation.completed, evaluation.episodes_total = DONE, completed, 3
                evaluation.mean_return, evaluation.mean_steps, evaluation.mean_speed = completed * 2.0, 500.0, 0.3
            session.flush()
            session.expunge(submission)
        return submission


    def finish_job(self, job_id: int, outcome) -> None:
        """Run a job's lease as a worker does (claim, then write its outcome as the job ends), with an
        outcome given here instead of computed in a sandbox."""
        from league.server.jobs.handlers import HANDLERS
        from league.server.jobs.leases import claim, complete

        assert claim(self.sessions, HANDLERS, job_id=job_id, attempt_id="test") is not None
        complete(self.sessions, HANDLERS, job_id=job_id, attempt_id="test", outcome=outcome)


def evaluation_outcome(completed: int, episodes: int = 3, settings: dict | None = None):
    """What an evaluation job returns (MetricsResult.to_dict()), made up: `completed` of `episodes` finished,
    recorded as run with `settings` (default: the test settings) on this simulator."""
    from league.evaluation import league_versions
    from league.server.jobs.evaluate import EvaluationOutcome

    settings = settings or Settings(_env_file=None, **league_test_settings()).default_evaluation()
    rows = [{"seed": 1000 + i, "steps": 100 + i, "return": float(completed), "mean_speed": 0.3,
             "outcome": "finished" if i < completed else "off_road", "reason": None} for i in range(episodes)]
    record = {**settings, "versions": league_versions(), "result_key": settings_key(settings)}
    return EvaluationOutcome({"episodes": rows, "completed": completed, "episodes_total": episodes,
                              "mean_return": float(completed), "mean_steps": 100.0, "mean_speed": 0.3,
                              "settings": record}, None, "evaluated in a test")


def league_test_settings() -> dict:
    """TEST_SETTINGS as keyword arguments of Settings."""
    return {key.removeprefix("LEAGUE_").lower(): value for key, value in TEST_SETTINGS.items()}


@contextlib.contextmanager
def in_process_league(kind: str, tmp_path: Path, prepare: Callable[[str], None] | None = None, **settings):
    """The app with the test settings (and `settings`) on a fresh database of `kind` (given first to
    `prepare(database_url)`, e.g. to hold an older schema's data); an instructor; no worker."""
    with fresh_backend(kind, tmp_path) as database_url:
        if prepare is not None:
            prepare(database_url)
        values = league_test_settings()
        values.update(public_cache_s=0)  # every answer fresh: tests independent of their order
        values.update(baselines_dir=tmp_path / "baselines")  # empty: the heuristic driver is the baseline
        settings = Settings(_env_file=None, **{**values, **settings}, data_dir=tmp_path / "data",
                            database_url=database_url)
        migrate(app_engine := make_engine(settings.resolved_database_url))  # as `league serve` does first
        app_engine.dispose()
        app = create_app(settings)
        with TestClient(app):  # the lifespan: the schema checked, the course, the baselines registered
            with make_sessionmaker(app.state.services.engine).begin() as session:
                _, token = crud.create_user(session, name="prof", role=INSTRUCTOR,
                                            course=crud.first_course(session))
            yield InProcessLeague(app, settings, token)
