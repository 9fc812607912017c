"""The evaluation job: the toolkit's `metrics_run` of a submission's sandboxed agent, with the
settings its evaluation holds (league.server.course.results queues them)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sqlalchemy import delete, insert
from sqlalchemy.orm import Session

from league.agents import AgentError
from league.evaluation import metrics_run
from league.track import TrackGenerationError
from league.server.core.clock import utcnow
from league.server.course.assignments import after_job
from league.server.db.models import DONE, FAILED, RUNNING, EpisodeResult, Evaluation, Job
from league.server.jobs.runner import JobRun
from league.server.sandbox.agent import SandboxedAgent
from league.server.sandbox.log import LogBuffer


@dataclass
class EvaluationOutcome:
    result: dict[str, Any] | None  # MetricsResult.to_dict()
    error: str | None
    log: str


class EvaluateSubmission:
    parallel_sandboxes = False  # one sandbox, a call at a time

    def begin(self, session: Session, job: Job) -> None:
        evaluation = session.get(Evaluation, job.evaluation_id)
        evaluation.status, evaluation.error = RUNNING, None

    def run(self, run: JobRun) -> EvaluationOutcome:
        submission = run.submission()
        with run.context.sessions() as session:
            settings = session.get(Evaluation, run.job.evaluation_id).settings
        limits = run.context.settings.sandbox_limits()
        log = LogBuffer(limits.log_limit)
        try:
            with SandboxedAgent(run.model_file(submission), submission.kind, limits,
                                name=submission.name, log=log, cancel=run.lease_lost) as agent:
                result = metrics_run(agent, episodes=settings["episodes"], seed=settings["seed"],
                                     **settings["env_options"])
        except AgentError as error:  # the model no longer starts (it passed validation: a changed runtime?)
            return EvaluationOutcome(None, error.reason, log.text())
        except (TypeError, ValueError, TrackGenerationError) as error:  # settings the simulator refuses: final
            return EvaluationOutcome(None, f"invalid evaluation settings: {error}", log.text())
        return EvaluationOutcome(result.to_dict(), None, log.text())

    def finish(self, session: Session, job: Job, outcome: EvaluationOutcome) -> list[int]:
        evaluation = session.get(Evaluation, job.evaluation_id)
        evaluation.log, evaluation.finished_at = outcome.log, utcnow()
        if outcome.result is None:
            evaluation.status, evaluation.error = FAILED, outcome.error
        else:
            _store_result(session, evaluation, outcome.result)
            evaluation.status, evaluation.error = DONE, None
        # the final it may decide, the private board it may complete
        return after_job(session, submission_id=job.submission_id, max_attempts=job.max_attempts)

    def give_up(self, session: Session, job: Job, reason: str) -> None:
        evaluation = session.get(Evaluation, job.evaluation_id)
        evaluation.status, evaluation.error = FAILED, f"the evaluation could not be completed: {reason}"
        evaluation.finished_at = utcnow()
        after_job(session, submission_id=job.submission_id, max_attempts=job.max_attempts)  # (polled: no wake-up)


def _store_result(session: Session, evaluation: Evaluation, result: dict[str, Any]) -> None:
    """Totals and episodes; replaces any earlier rows of this evaluation (idempotent)."""
    session.execute(delete(EpisodeResult).where(EpisodeResult.evaluation_id == evaluation.id))
    rows = [{"evaluation_id": evaluation.id, "index": i, "seed": e["seed"], "steps": e["steps"],
             "episode_return": e["return"], "mean_speed": e["mean_speed"], "outcome": e["outcome"],
             "reason": e["reason"]} for i, e in enumerate(result["episodes"])]
    if rows:  # one bulk INSERT of plain rows: no ORM object (and unit of work) per episode
        session.execute(insert(EpisodeResult), rows)
    for key in ("completed", "episodes_total", "mean_return", "mean_steps", "mean_speed"):
        setattr(evaluation, key, result[key])
    # what produced it, as the worker's metrics_run recorded it: its simulator may not be the API's
    record = result["settings"]
    evaluation.result_settings, evaluation.result_key, evaluation.versions = \
        record, record["result_key"], record["versions"]
    session.expire(evaluation, ["episodes"])
