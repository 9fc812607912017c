"""A populated league from the first start: the default course, and the baseline agents (*.onnx|*.pt
of LEAGUE_BASELINES_DIR, by default the ones bundled with the package, league/baselines/agents)
registered under the `baselines` account and evaluated.

In an empty LEAGUE_BASELINES_DIR the heuristic driver is exported to ONNX
(league.agents.export_heuristic_onnx), so a new user sees a working leaderboard at once.
"""
from __future__ import annotations

import logging
from pathlib import Path

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from league.agents import export_heuristic_onnx
from league.server.core.config import Settings
from league.server.db import crud
from league.server.db.models import BASELINE, Course
from league.server.jobs.queue import JobQueue
from league.server.storage import BlobStore
from league.validation.files import model_kind_of

log = logging.getLogger("league.server.bootstrap")


def ensure_course(sessions: sessionmaker[Session], settings: Settings) -> Course:
    try:
        with sessions.begin() as session:
            return crud.get_or_create_course(session, name=crud.DEFAULT_COURSE,
                                             evaluation=settings.default_evaluation(),
                                             board_visibility=settings.board_visibility)
    except IntegrityError:  # created by another process starting at the same time
        with sessions() as session:
            return crud.get_or_create_course(session, name=crud.DEFAULT_COURSE,
                                             evaluation=settings.default_evaluation(),
                                             board_visibility=settings.board_visibility)


def baseline_files(directory: Path) -> list[Path]:
    files = sorted(p for p in directory.glob("*") if p.is_file() and model_kind_of(p.name))
    if files:
        return files
    directory.mkdir(parents=True, exist_ok=True)
    log.info("no bundled baselines in %s: exporting the heuristic driver to ONNX", directory)
    return [export_heuristic_onnx(directory / "heuristic.onnx")]


def bootstrap(settings: Settings, sessions: sessionmaker[Session], queue: JobQueue, store: BlobStore) -> list[int]:
    """Register the baselines once (when their account does not exist yet); return the queued job ids."""
    ensure_course(sessions, settings)
    if not settings.bootstrap:
        return []
    with sessions() as session:
        if crud.user_by_name(session, name=crud.BASELINES_USER) is not None:
            return []
    files = baseline_files(settings.resolved_baselines_dir)
    try:
        job_ids = _register(sessions, store, files, settings.max_job_attempts)
    except (IntegrityError, crud.InvalidAccount):  # another process registered them first
        return []
    for job_id in job_ids:
        queue.enqueue(job_id)
    log.info("registered %d baseline agents: %s", len(files), ", ".join(p.name for p in files))
    return job_ids


def _register(sessions: sessionmaker[Session], store: BlobStore, files: list[Path], max_attempts: int) -> list[int]:
    job_ids = []
    with sessions.begin() as session:
        owner, _ = crud.create_user(session, name=crud.BASELINES_USER, role=BASELINE, course=None, with_token=False)
        # evaluated with the first course's default assignment; other assignments queue their own (results)
        assignment = crud.default_assignment(session, course_id=crud.first_course(session).id)
        for path in files:
            sha256, size = store.add_file(path)
            crud.save_blob(session, sha256=sha256, data=path.read_bytes())
            submission, job = crud.create_submission(session, owner=owner, assignment=assignment, name=path.stem,
                                                     filename=path.name, kind=model_kind_of(path.name), sha256=sha256,
                                                     size=size, max_attempts=max_attempts)
            submission.public = True
            job_ids.append(job.id)
    return job_ids
