"""The audit log: who revoked, replaced a token, cancelled, re-ran, changed settings, created,
imported or deleted accounts, created or raced championship rounds, had submissions probed, changed
who sees the boards, created courses; and every action that changes a grade or a deadline: an assignment created or
edited (its tracks, due time, late policy, quota), an extension, a rubric, a publication (by an
instructor, or by the assignment itself), a re-run, a cancelled job, a backup, a restore -- with the
values before and after (`changes`).

`record` adds the event to the caller's session, so it is committed with the change it records
(or not at all). Details hold ids and figures, never tokens; a deleted student's name is personal
data and is not kept (the event names them by id).
"""
from __future__ import annotations

import copy
import json
from datetime import datetime
from typing import Any

from sqlalchemy import func, or_, select
from sqlalchemy.orm import Session

from league.server.db.models import AuditEvent, User

CLI_ACTOR = "league CLI"  # admin commands run on the server's machine: no account
SERVER_ACTOR = "league server"  # what the server does by itself (an assignment publishing itself)
AUDIT_COLUMNS = ["at", "actor_id", "actor_name", "action", "target_kind", "target_id", "details"]

# actions (one vocabulary for the API, the console and the CSV)
REVOKE, TOKEN, CANCEL, RERUN = "user.revoke", "user.token", "job.cancel", "evaluation.rerun"
SETTINGS = "settings.evaluation"
CREATE_USER, IMPORT_ROSTER, DELETE_USER = "user.create", "user.import", "user.delete"
CREATE_CHAMPIONSHIP, RUN_ROUND, RETRY_ROUND = "championship.create", "round.run", "round.retry"
PROBE = "integrity.probe"
PRIVACY = "settings.privacy"
CREATE_COURSE = "course.create"
CREATE_ASSIGNMENT, EDIT_ASSIGNMENT, EXTENSION = "assignment.create", "assignment.edit", "assignment.extension"
RUBRIC, PUBLISH = "assignment.rubric", "assignment.publish"
BACKUP, RESTORE = "league.backup", "league.restore"


def record(session: Session, *, actor: User | None, action: str, target_kind: str, target_id: int | None = None,
           course_id: int | None = None, actor_name: str = CLI_ACTOR, **details: Any) -> AuditEvent:
    """Add an event to `session` (committed with the caller's change). actor None: an admin command
    (or `actor_name`: the server itself)."""
    event = AuditEvent(actor_id=actor.id if actor else None, actor_name=actor.name if actor else actor_name,
                       course_id=course_id if course_id is not None else (actor.course_id if actor else None),
                       action=action, target_kind=target_kind, target_id=target_id, details=details)
    session.add(event)
    return event


def snapshot(row: Any, fields: tuple[str, ...] | list[str]) -> dict[str, Any]:
    """The `fields` of a row as the log keeps them (times as ISO text, as the API shows them)."""
    return {name: _logged(getattr(row, name)) for name in fields}


def changes(before: dict[str, Any], after: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """{"before": ..., "after": ...} of the values that differ (empty dicts: nothing changed)."""
    changed = [name for name in after if before.get(name) != after[name]]
    return {"before": {name: before.get(name) for name in changed}, "after": {name: after[name] for name in changed}}


def _logged(value: Any) -> Any:
    if isinstance(value, datetime):
        return value.isoformat(timespec="seconds")
    return copy.deepcopy(value)  # a JSON column's dict: the row may change it in place afterwards


def events_page(session: Session, *, course_id: int | None, offset: int, limit: int) -> tuple[list[AuditEvent], int]:
    """The course's events and the admin commands', newest first."""
    where = or_(AuditEvent.course_id == course_id, AuditEvent.course_id.is_(None))
    total = session.scalar(select(func.count()).select_from(AuditEvent).where(where))
    events = session.scalars(select(AuditEvent).where(where).order_by(AuditEvent.id.desc())
                             .offset(offset).limit(limit)).all()
    return list(events), total


def csv_row(event: AuditEvent) -> list:
    details = "; ".join(f"{key}={json.dumps(value, sort_keys=True) if isinstance(value, (dict, list)) else value}"
                        for key, value in sorted(event.details.items()))  # before/after: JSON, as the API shows
    return [event.at.isoformat(timespec="seconds"), event.actor_id, event.actor_name, event.action,
            event.target_kind, event.target_id, details]
