"""The secret probe sets through the app in this process, on SQLite and on PostgreSQL: queued as
the instructor's jobs, read by the report only, nothing of them in a student's answers, erased with
the student (the sandboxed runs: tests/system/api/test_integrity.py)."""
from __future__ import annotations

import numpy as np
import pytest
from sqlalchemy import func, select

from league.server.course.integrity import secret_key
from league.server.db.models import PROBE, SECRET_PROBE, Assignment, Job, SubmissionProbe
from league.server.jobs.probe import ProbeOutcome
from league.validation.probes import SECRET_PROBES, Probe, probe_actions_bytes, probe_key

from .api.in_process import in_process_league
from .backends import BACKENDS

PRINTED = "the model printed this while it met the private tracks"


@pytest.mark.parametrize("kind", BACKENDS)
def test_secret_probes_are_the_instructors_jobs_read_by_the_report_only_and_erased_with_the_student(kind, tmp_path):
    with in_process_league(kind, tmp_path, bootstrap=False) as league:
        student, ann = league.student("ann")
        submission = league.submission(student, evaluated=False)  # ready, no actions on any set yet
        prof = league.client(league.instructor_token)
        [waiting] = prof.get("/api/integrity").json()["not_compared"]
        assert (waiting["id"], waiting["reason"]) == (submission.id, "not yet probed")

        assert prof.post("/api/integrity/probe").json() == {"queued": [submission.id]}

        with league.sessions() as session:
            jobs = {job.kind: job for job in session.scalars(select(Job).where(Job.submission_id == submission.id,
                                                                                Job.kind.in_((PROBE, SECRET_PROBE))))}
            key = secret_key(session.get(Assignment, submission.assignment_id), 5)
        assert jobs[PROBE].owner_id == student.id and jobs[SECRET_PROBE].owner_id != student.id  # the instructor's
        assert prof.post("/api/integrity/probe").json() == {"queued": []}  # waiting: not queued twice
        rng = np.random.default_rng(0)
        league.finish_job(jobs[PROBE].id, ProbeOutcome([Probe(probe_key(5), probe_actions_bytes(
            rng.uniform(-1, 1, (64, 2))))], ""))
        seen_by_ann = ann.get(f"/api/submissions/{submission.id}").json()
        league.finish_job(jobs[SECRET_PROBE].id, ProbeOutcome([Probe(key, probe_actions_bytes(
            rng.uniform(-1, 1, (SECRET_PROBES, 2))))], PRINTED))

        report = prof.get("/api/integrity").json()
        assert (report["not_compared"], report["compared"]) == ([], 1)
        # the student: their submission reads as before, no job of theirs is waiting, nothing printed shows
        assert ann.get(f"/api/submissions/{submission.id}").json() == seen_by_ann
        for answer in (ann.get(f"/api/submissions/{submission.id}"), ann.get("/api/submissions"), ann.get("/api/me")):
            assert key not in answer.text and PRINTED not in answer.text and "secret_probe" not in answer.text
        assert ann.get("/api/jobs").status_code == 403

        with league.sessions() as session:
            [row] = session.scalars(select(SubmissionProbe)).all()
            assert (row.submission_id, row.probe_key, len(row.actions), row.error) == (submission.id, key,
                                                                                       SECRET_PROBES * 8, None)
        assert prof.delete(f"/api/users/{student.id}").status_code == 204
        with league.sessions() as session:
            assert session.scalar(select(func.count()).select_from(SubmissionProbe)) == 0
