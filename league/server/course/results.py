"""Which evaluation results count: those of the current settings.

An evaluation's `result_key` (league.evaluation.result_key) names the settings and the simulator
version that produced it. Boards and grades rank only results of the current key: the settings of
the submission's assignment on this server's simulator. Any other result is stale, shown apart, until the
submission is evaluated again; a change of the settings queues those re-evaluations at low priority.

This module is the one home of "the current settings" (an assignment's public ones) and of what a
change of them queues.
"""
from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy.orm import Session

from league.evaluation import result_key
from league.server.db import crud
from league.server.db.models import BASELINE, LOW, NORMAL, PUBLIC_TRACKS, READY, Assignment, Job, Submission

log = logging.getLogger("league.server.course.results")
SUPERSEDED = ("superseded: the evaluation settings changed before it ran, "
              "to settings its submission has an evaluation of")


_KEYS: dict[str, str] = {}  # settings_key by the settings' JSON text: a course has a few settings, read at every answer
MAX_KEYS = 1024


def settings_key(settings: dict[str, Any]) -> str:
    """The result key of evaluation settings on this simulator. Settings the simulator refuses
    (they fail every evaluation) get a key of their own text. Kept by the settings' JSON text, of
    which the key is a function (result_key hashes the options' JSON): computing it (the options'
    defaults filled in, each checked) costs more than a status answer's queries."""
    try:
        text = json.dumps(settings, sort_keys=True)
    except (TypeError, ValueError):
        return _settings_key(settings)
    key = _KEYS.get(text)
    if key is None:
        if len(_KEYS) >= MAX_KEYS:
            _KEYS.clear()
        key = _KEYS[text] = _settings_key(settings)
    return key


def _settings_key(settings: dict[str, Any]) -> str:
    try:
        return result_key(settings["seed"], settings["episodes"], settings["env_options"])
    except (TypeError, ValueError):
        text = json.dumps(settings, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def current_key(assignment: Assignment | None) -> str | None:
    """The key that results must have to count on the assignment's public board (None: nothing counts)."""
    return None if assignment is None else settings_key(assignment.evaluation_settings())


def submissions_current_keys(session: Session, submissions: list[Submission],
                             course_id: int | None = None) -> dict[int, str | None]:
    """Each submission's current key, by submission id: that of its assignment; a baseline's (each course
    evaluates the baselines for itself), with `course_id`, that of the course's default assignment."""
    keys: dict[int | None, str | None] = {}
    for assignment_id in {s.assignment_id for s in submissions}:
        keys[assignment_id] = current_key(session.get(Assignment, assignment_id) if assignment_id else None)
    shown = {s.id: keys[s.assignment_id] for s in submissions}
    if course_id is not None and any(s.owner.role == BASELINE for s in submissions):
        baseline_key = current_key(crud.default_assignment(session, course_id=course_id))
        shown.update({s.id: baseline_key for s in submissions if s.owner.role == BASELINE})
    return shown


def queue_evaluation(session: Session, *, submission: Submission, max_attempts: int,
                     assignment: Assignment | None = None, priority: int = NORMAL) -> Job:
    """A new public evaluation with the assignment's current settings (by default the submission's)."""
    assignment = assignment or session.get(Assignment, submission.assignment_id)
    settings = assignment.evaluation_settings()
    _, job = crud.create_evaluation(session, submission=submission, assignment=assignment, settings=settings,
                                    result_key=settings_key(settings), max_attempts=max_attempts, priority=priority,
                                    track=PUBLIC_TRACKS)
    return job


@dataclass
class SettingsChange:
    """What a change of the settings did to the queue (submission ids)."""

    queued: list[Job] = field(default_factory=list)  # new re-evaluations, LOW priority: send them to the queue
    retargeted: list[int] = field(default_factory=list)  # queued evaluations that take the new settings instead
    superseded: list[int] = field(default_factory=list)  # queued evaluations no longer needed

    @property
    def reevaluated(self) -> list[int]:
        return sorted([job.submission_id for job in self.queued] + self.retargeted)


def change_settings(session: Session, *, assignment: Assignment, settings: dict[str, Any], max_attempts: int,
                    unchanged: str | None = None) -> SettingsChange:
    """Give the assignment new public settings and queue what they call for (in the caller's transaction).

    Evaluations of the assignment still queued take the new settings (a new upload keeps its place
    in the queue), unless their submission has a result of them already (they are superseded). Every
    other ready submission of the assignment, and every baseline, without a result of the new
    settings (done, running or queued) is queued for re-evaluation at LOW priority. Settings with the
    current key (the same, perhaps written otherwise) queue nothing; a new assignment passes
    `unchanged=""` (its baselines are evaluated).
    """
    key = settings_key(settings)
    unchanged = settings_key(assignment.evaluation_settings()) if unchanged is None else unchanged
    crud.set_evaluation_settings(session, assignment=assignment, seed=settings["seed"],
                                 episodes=settings["episodes"], env_options=settings["env_options"])
    change = SettingsChange()
    if key == unchanged:
        return change
    covered = crud.submissions_with_results(session, result_key=key, course_id=assignment.course_id)
    for evaluation_id, submission_id, job_id in crud.queued_evaluations(session, assignment_id=assignment.id,
                                                                         other_than=key):
        if submission_id in covered:
            if crud.supersede_evaluation(session, evaluation_id=evaluation_id, job_id=job_id, reason=SUPERSEDED):
                change.superseded.append(submission_id)
        elif crud.retarget_evaluation(session, evaluation_id=evaluation_id, settings=settings, result_key=key):
            change.retargeted.append(submission_id)
            covered.add(submission_id)
    # each owner's newest submission first: the fair queue serves owners in turn, so every student's
    # latest agent is back on the board before anyone's older ones
    for submission in reversed(crud.course_submissions(session, course_id=assignment.course_id, status=READY,
                                                       assignment_id=assignment.id)):
        if submission.id not in covered:
            change.queued.append(queue_evaluation(session, submission=submission, max_attempts=max_attempts,
                                                  assignment=assignment, priority=LOW))
    log.info("assignment %s: new evaluation settings %s; %d re-evaluations queued, %d queued evaluations "
             "retargeted, %d superseded", assignment.id, key, len(change.queued), len(change.retargeted),
             len(change.superseded))
    return change
