"""The statuses a submission, an evaluation, a job, a race and a championship round go through: the
words the database stores and the API answers, written once for the server, the client and the pages
(league.server.pages hands them to the JavaScript). Plain strings, no imports: the toolkit reads them
without the server (tests/test_imports.py).
"""
from __future__ import annotations

# a submission's (what students see): waiting for its validation, being validated, then accepted, refused
# (the model's fault: its error says why) or not validated (the sandbox or the worker could not run it)
PENDING, VALIDATING, READY, REJECTED, FAILED = "pending", "validating", "ready", "rejected", "failed"
SUBMISSION_STATUSES = (PENDING, VALIDATING, READY, REJECTED, FAILED)
VALIDATED = (READY, REJECTED, FAILED)  # a submission's once its validation is over: nothing changes after

# an evaluation's and a job's: waiting for a worker, claimed by one, then done or failed
QUEUED, RUNNING, DONE = "queued", "running", "done"
JOB_STATUSES = (QUEUED, RUNNING, DONE, FAILED)
EVALUATION_STATUSES = JOB_STATUSES

# a race's and a championship round's: PENDING, RUNNING, then DONE or FAILED
RACE_STATUSES = (PENDING, RUNNING, DONE, FAILED)
ENDED = (DONE, FAILED)  # an evaluation's, a job's, a race's or a round's once over: nothing changes after


def by_name() -> dict[str, str | tuple[str, ...]]:
    """Every status word and group above by its name, as the pages read them (league.server.pages)."""
    return {name: value for name, value in globals().items() if name.isupper()}
