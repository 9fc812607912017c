"""The probe jobs, for the integrity report (league.server.course.integrity), queued at low priority by an
instructor (POST /api/integrity/probe); the submission's status is left alone.

* `probe`: the public probe set's actions of a submission validated before they were recorded (or
  on another probe set); owned by the submission's owner, as its validation was.
* `secret_probe`: its actions on the secret probe sets (drawn on private tracks) of the assignments
  it is compared in: its own assignment's, or for a baseline every assignment of the instructor's
  course. Owned by the instructor who queued it, so it is in no student's job count or queue, and
  what the sandbox printed (the model saw private-track observations) stays in no student's log.
"""
from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from league.server.db.models import BASELINE, Assignment, Job, Submission, SubmissionProbe, User
from league.server.jobs.runner import JobRun
from league.server.sandbox.validation import probe_model
from league.validation.probes import Probe, secret_probe_observations


@dataclass
class ProbeOutcome:
    probes: list[Probe]
    log: str


class ProbeSubmission:
    parallel_sandboxes = False

    def begin(self, session: Session, job: Job) -> None:
        pass

    def run(self, run: JobRun) -> ProbeOutcome:
        submission = run.submission()
        probes, log = probe_model(run.model_file(submission), submission.kind, submission.obs_dim,
                                  run.context.settings.sandbox_limits(), name=submission.name, cancel=run.lease_lost)
        return ProbeOutcome(probes, log)

    def finish(self, session: Session, job: Job, outcome: ProbeOutcome) -> list[int]:
        submission = session.get(Submission, job.submission_id)
        [probe] = outcome.probes
        submission.probe_key, submission.probe_actions = probe.key, probe.actions
        if probe.error:  # kept where the validation's own reasons are
            submission.log = f"{submission.log or ''}\n[probe] {probe.error}".lstrip()
        return []

    def give_up(self, session: Session, job: Job, reason: str) -> None:
        pass  # the submission stays unprobed; the job's error says why


class SecretProbeSubmission(ProbeSubmission):
    def run(self, run: JobRun) -> ProbeOutcome:
        submission = run.submission()
        with run.context.sessions() as session:
            settings = [a.private_settings() for a in probed_assignments(session, submission, run.job.owner_id)]
        secret = tuple(secret_probe_observations(s, submission.obs_dim) for s in settings)
        if not secret:
            return ProbeOutcome([], "")
        probes, log = probe_model(run.model_file(submission), submission.kind, submission.obs_dim,
                                  run.context.settings.sandbox_limits(), name=submission.name, cancel=run.lease_lost,
                                  secret_sets=secret)
        return ProbeOutcome(probes, log)

    def finish(self, session: Session, job: Job, outcome: ProbeOutcome) -> list[int]:
        for probe in outcome.probes:  # a re-run replaces its rows
            session.execute(delete(SubmissionProbe).where(SubmissionProbe.submission_id == job.submission_id,
                                                          SubmissionProbe.probe_key == probe.key))
            session.add(SubmissionProbe(submission_id=job.submission_id, probe_key=probe.key, actions=probe.actions,
                                        error=probe.error))
        return []


def probed_assignments(session: Session, submission: Submission, instructor_id: int | None) -> list[Assignment]:
    """The assignments whose secret sets a submission is compared on: its own, or for a baseline
    (on every board) those of the instructor's course."""
    if submission.owner.role != BASELINE:
        return [a for a in [session.get(Assignment, submission.assignment_id)] if a is not None]
    instructor = session.get(User, instructor_id) if instructor_id is not None else None
    if instructor is None or instructor.course_id is None:
        return []
    return list(session.scalars(select(Assignment).where(Assignment.course_id == instructor.course_id)
                                .order_by(Assignment.id)))
