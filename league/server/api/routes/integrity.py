"""The integrity report (instructors): submissions of different students that are one file or one
policy (league.server.course.integrity). Nothing is blocked: the instructor decides."""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response
from sqlalchemy.orm import Session

from league.server.course import audit
from league.server.api.deps import (
    MAX_ID, InstructorUser, QueueDep, SessionDep, SettingsDep, csv_response, user_course,
)
from league.server.core.config import BUNDLED_BASELINES, Settings
from league.server.db import crud
from league.server.db.models import User
from league.server.course.integrity import (
    CSV_COLUMNS, Candidate, Report, bundled_digests, candidates, integrity_report, queue_probes,
    queue_secret_probes, report_rows, secret_unprobed_submissions, unprobed_submissions,
)
from league.server.api.schemas import (
    IntegrityGroup, IntegrityReport, IntegritySubmission, ProbesQueued, UncomparedSubmission,
)
from league.validation.probes import PROBES

router = APIRouter(prefix="/integrity", tags=["integrity"])
Assignment = Annotated[int | None, Query(ge=1, le=MAX_ID,
                                         description="one assignment's submissions (once submissions belong to "
                                                     "assignments); default: every submission of the course")]


def course_report(settings: Settings, session: Session, instructor: User,
                  assignment: int | None) -> tuple[Report, list[Candidate]]:
    submissions = candidates(session, course_id=user_course(session, instructor).id, assignment_id=assignment)
    bundled = bundled_digests([settings.resolved_baselines_dir, BUNDLED_BASELINES])
    return integrity_report(submissions, bundled=bundled, tolerance=settings.integrity_tolerance), submissions


@router.get("", response_model=IntegrityReport)
def read_integrity(settings: SettingsDep, session: SessionDep, instructor: InstructorUser,
                   assignment: Assignment = None) -> IntegrityReport:
    """Groups of submissions of different students (or of a student and a baseline) with identical
    files or alike behaviour on a probe set (public or secret); and the submissions not yet compared
    on every set."""
    report, submissions = course_report(settings, session, instructor, assignment)
    return IntegrityReport(
        tolerance=report.tolerance, probes=PROBES, submissions=len(submissions), compared=report.compared,
        groups=[IntegrityGroup(kind=g.kind, students=g.students, baseline=g.baseline, distance=g.distance,
                               submissions=[_submission(m) for m in g.members]) for g in report.groups],
        not_compared=[UncomparedSubmission(**_submission(m).model_dump(), reason=why) for m, why in report.unprobed])


@router.get(".csv", response_class=Response, responses={200: {"content": {"text/csv": {}}}})
def read_integrity_csv(settings: SettingsDep, session: SessionDep, instructor: InstructorUser,
                       assignment: Assignment = None) -> Response:
    """The report as CSV: one line per submission of each group (numbered), then the submissions
    compared by file only (kind not_compared, the reason in `note`)."""
    report, _ = course_report(settings, session, instructor, assignment)
    return csv_response(CSV_COLUMNS, report_rows(report), "integrity.csv")


@router.post("/probe", response_model=ProbesQueued)
def probe_submissions(settings: SettingsDep, queue: QueueDep, session: SessionDep, instructor: InstructorUser,
                      assignment: Assignment = None) -> ProbesQueued:
    """Record the actions of the ready submissions that have none on a probe set they are compared
    on, as low-priority jobs: on the public set (validated before it was recorded, or on another
    simulator), and on their assignments' secret sets (jobs of yours: no student sees them)."""
    course = user_course(session, instructor)
    submissions = candidates(session, course_id=course.id, assignment_id=assignment)
    # a baseline's public probe is a job of the course that registered it (crud.course_jobs): queued from there
    # only; the secret sets are each course's own, probed by its instructor
    registered = crud.registered_baselines(session, course_id=course.id)
    public = unprobed_submissions(session, [c for c in submissions if not c.baseline or c.id in registered])
    secret = secret_unprobed_submissions(session, submissions)
    job_ids = queue_probes(session, submission_ids=public, max_attempts=settings.max_job_attempts) + \
        queue_secret_probes(session, submission_ids=secret, instructor=instructor,
                            max_attempts=settings.max_job_attempts)
    ids = sorted(set(public) | set(secret))
    if ids:
        audit.record(session, actor=instructor, action=audit.PROBE, target_kind="course", target_id=course.id,
                     queued=len(ids))
    session.commit()
    for job_id in job_ids:
        queue.enqueue(job_id)
    return ProbesQueued(queued=ids)


def _submission(m: Candidate) -> IntegritySubmission:
    return IntegritySubmission(id=m.id, name=m.name, owner=m.owner, baseline=m.baseline, kind=m.kind,
                               sha256=m.sha256, created_at=m.created_at)
