"""Every kind of job, by the name stored in `Job.kind`: the one place a new kind is added."""
from __future__ import annotations

from league.server.db.models import EVALUATE, PROBE, RACE, SECRET_PROBE, VALIDATE
from league.server.jobs.evaluate import EvaluateSubmission
from league.server.jobs.probe import ProbeSubmission, SecretProbeSubmission
from league.server.jobs.race import RunRace
from league.server.jobs.runner import JobHandler
from league.server.jobs.validate import ValidateSubmission

HANDLERS: dict[str, JobHandler] = {
    VALIDATE: ValidateSubmission(),
    EVALUATE: EvaluateSubmission(),
    RACE: RunRace(),
    PROBE: ProbeSubmission(),
    SECRET_PROBE: SecretProbeSubmission(),
}
