"""The validation job: static checks, load and a timed dry run of an upload, in a sandbox."""
from __future__ import annotations

from sqlalchemy.orm import Session

from league.server.course.assignments import after_job
from league.server.course.results import queue_evaluation
from league.server.db import crud
from league.server.db.models import BASELINE, FAILED, READY, REJECTED, VALIDATING, Job, Submission
from league.server.jobs.runner import JobRun
from league.server.sandbox.validation import validate_model
from league.validation.report import ValidationReport


class ValidateSubmission:
    parallel_sandboxes = False

    def begin(self, session: Session, job: Job) -> None:
        submission = session.get(Submission, job.submission_id)
        submission.status, submission.error = VALIDATING, None

    def run(self, run: JobRun) -> ValidationReport:
        submission = run.submission()
        return validate_model(run.model_file(submission), submission.kind, run.context.settings.sandbox_limits())

    def finish(self, session: Session, job: Job, report: ValidationReport) -> list[int]:
        submission = session.get(Submission, job.submission_id)
        submission.log = report.log
        if not report.ok:
            submission.status, submission.error = REJECTED, report.error
            crud.forget_blob_unless_used(session, sha256=submission.sha256)  # the stores sweep their copies
            # a candidate of a frozen final drops out: the final may be decided now
            return after_job(session, submission_id=submission.id, max_attempts=job.max_attempts)
        submission.status, submission.error, submission.obs_dim = READY, None, report.obs_dim
        if report.probe is not None:
            submission.probe_key, submission.probe_actions = report.probe.key, report.probe.actions
        if submission.owner.role == BASELINE:  # a reference on every assignment's board
            return [queue_evaluation(session, submission=submission, max_attempts=job.max_attempts, assignment=a).id
                    for a in crud.all_assignments(session)]
        return [queue_evaluation(session, submission=submission, max_attempts=job.max_attempts).id]

    def give_up(self, session: Session, job: Job, reason: str) -> None:
        submission = session.get(Submission, job.submission_id)
        submission.status, submission.error = FAILED, f"the validation could not be completed: {reason}"
        after_job(session, submission_id=submission.id, max_attempts=job.max_attempts)  # (polled: no wake-up)
