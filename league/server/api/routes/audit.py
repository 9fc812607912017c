"""The audit log, for instructors: who did what (league.server.course.audit)."""
from __future__ import annotations

from fastapi import APIRouter, Response

from league.server.api.deps import InstructorUser, PageNumber, PageSize, SessionDep, csv_response
from league.server.api.schemas import AuditEventOut, AuditPage
from league.server.course import audit

router = APIRouter(prefix="/audit", tags=["audit"])
CSV_ROWS = 100_000  # the newest events a CSV export holds: a bound on one answer's size


@router.get("", response_model=AuditPage)
def read_audit(instructor: InstructorUser, session: SessionDep, page: PageNumber = 1, size: PageSize = 50) -> AuditPage:
    """Your course's audit events and the admin commands', newest first."""
    events, total = audit.events_page(session, course_id=instructor.course_id, offset=(page - 1) * size, limit=size)
    return AuditPage(items=[AuditEventOut.model_validate(e) for e in events], total=total)


@router.get(".csv", response_class=Response, responses={200: {"content": {"text/csv": {}}}})
def read_audit_csv(instructor: InstructorUser, session: SessionDep) -> Response:
    """The same events as a spreadsheet (the newest 100,000)."""
    events, _ = audit.events_page(session, course_id=instructor.course_id, offset=0, limit=CSV_ROWS)
    return csv_response(audit.AUDIT_COLUMNS, (audit.csv_row(e) for e in events), "audit.csv")
