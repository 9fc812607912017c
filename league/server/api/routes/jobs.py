"""Jobs, for instructors watching the workers: the course's jobs, and cancelling one."""
from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, HTTPException, Query, status

from league.server.api.deps import Id, InstructorUser, SessionDep, SessionsDep
from league.server.api.schemas import JobOut
from league.server.course import audit
from league.server.db import crud
from league.server.db.models import Job
from league.server.jobs import leases
from league.server.jobs.handlers import HANDLERS
from league.statuses import JOB_STATUSES

router = APIRouter(prefix="/jobs", tags=["jobs"])
JobStatus = Literal[JOB_STATUSES]


@router.get("", response_model=list[JobOut])
def read_jobs(instructor: InstructorUser, session: SessionDep, status: JobStatus | None = None,
              limit: int = Query(100, ge=1, le=1000)) -> list[Job]:
    """The course's latest jobs, newest first, optionally of one status."""
    return crud.course_jobs(session, course_id=instructor.course_id, status=status, limit=limit)


@router.post("/{job_id}/cancel", response_model=JobOut)
def cancel_job(job_id: Id, instructor: InstructorUser, session: SessionDep, sessions: SessionsDep) -> Job:
    """Stop a queued or running job of your course: it fails as cancelled, and so does what it was for
    (a running job's worker stops at its next heartbeat)."""
    job = crud.course_job(session, course_id=instructor.course_id, job_id=job_id)
    if job is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no job {job_id} in your course")
    before = audit.snapshot(job, ["status"])
    if not leases.cancel(sessions, HANDLERS, job_id=job_id,
                         reason=f"cancelled by {instructor.name}"):
        raise HTTPException(status.HTTP_409_CONFLICT, f"job {job_id} is already over")
    session.expire_all()
    job = crud.course_job(session, course_id=instructor.course_id, job_id=job_id)
    audit.record(session, actor=instructor, action=audit.CANCEL, target_kind="job", target_id=job_id, kind=job.kind,
                 submission_id=job.submission_id, evaluation_id=job.evaluation_id, race_id=job.race_id,
                 **audit.changes(before, audit.snapshot(job, ["status"])))
    session.commit()
    return job
