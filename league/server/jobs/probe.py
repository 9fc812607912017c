"""The probe job: the probe set's actions of a submission validated before they were recorded (or
on another probe set), in a sandbox, for the integrity report (league.server.integrity). Queued
at low priority by an instructor (POST /api/integrity/probe); the submission's status is left alone."""
from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy.orm import Session

from league.server.db.models import Job, Submission
from league.server.jobs.runner import JobRun
from league.server.sandbox.validation import probe_model
from league.validation.probes import Probe


@dataclass
class ProbeOutcome:
    probe: Probe
    log: str


class ProbeSubmission:
    parallel_sandboxes = False

    def begin(self, session: Session, job: Job) -> None:
        pass

    def run(self, run: JobRun) -> ProbeOutcome:
        submission = run.submission()
        probe, log = probe_model(run.model_file(submission), submission.kind, submission.obs_dim,
                                 run.context.settings.sandbox_limits(), name=submission.name, cancel=run.lease_lost)
        return ProbeOutcome(probe, log)

    def finish(self, session: Session, job: Job, outcome: ProbeOutcome) -> list[int]:
        submission = session.get(Submission, job.submission_id)
        submission.probe_key, submission.probe_actions = outcome.probe.key, outcome.probe.actions
        if outcome.probe.error:  # kept where the validation's own reasons are
            submission.log = f"{submission.log or ''}\n[probe] {outcome.probe.error}".lstrip()
        return []

    def give_up(self, session: Session, job: Job, reason: str) -> None:
        pass  # the submission stays unprobed; the job's error says why
