"""Deleting a student: their data erased, not hidden (`league users delete`, DELETE /api/users/{id}).

Erased: the account and its token, its submissions, their evaluations (public and private), episodes
and jobs, its own state in each assignment (extension, selection, frozen final: its grade goes with
it), the model files no other submission uses, the friendly races no other student's car took part
in, and the friendly races with the student's car still to run. Rows that only name the student as
their creator (races kept, championships, accounts) lose the name (NULL): every foreign key to the
account is followed (`_forget`), so a table added later is erased too.
Kept: the races and championship heats other students took part in, with the student's cars
shown as DELETED (entrant, classification and replay; the race log loses the car's output) and
their submission ids replaced by the negated id, which no row ever gets: standings keep every
result and every point, and a submission created later cannot inherit them (SQLite may hand a
deleted row's id out again). A championship heat still to race with the student's car refuses
the deletion until it is over (its worker holds the names in memory).
"""
from __future__ import annotations

import gzip
import json
from dataclasses import dataclass, field

from sqlalchemy import Engine, delete, or_, select, update
from sqlalchemy.orm import Session

from league.server.db.models import (
    DELETED, DONE, FAILED, STUDENT, Base, Blob, ChampionshipRound, EpisodeResult, Evaluation, Job, Race, RaceReplay,
    Submission, User, utcnow,
)
from league.server.jobs.race import car_name

ERASED_IN_STEPS = {Submission.__table__, Evaluation.__table__, EpisodeResult.__table__, Job.__table__}


class DeletionRefused(Exception):
    """The student cannot be deleted now (the message says why and when)."""


@dataclass
class Erased:
    """What a deletion removed: counts for the audit log, and the files to remove from the store."""

    submissions: int = 0
    evaluations: int = 0
    races_deleted: int = 0
    races_kept: int = 0
    blobs: list[str] = field(default_factory=list)

    def summary(self) -> dict:
        return {"submissions": self.submissions, "evaluations": self.evaluations, "races_deleted": self.races_deleted,
                "races_kept": self.races_kept, "files": len(self.blobs)}


def delete_student(session: Session, *, user: User) -> Erased:
    """Erase `user` (a student) in the caller's transaction (callers commit, then remove
    `Erased.blobs` from their store)."""
    if user.role != STUDENT:
        raise DeletionRefused(f"{user.role} accounts are not deleted: only students'")
    submissions = list(session.scalars(select(Submission).where(Submission.owner_id == user.id)))
    ids = {s.id for s in submissions}
    erased = Erased(submissions=len(submissions))
    _erase_races(session, user, ids, erased)
    evaluation_ids = list(session.scalars(select(Evaluation.id).where(Evaluation.submission_id.in_(ids))))
    erased.evaluations = len(evaluation_ids)
    _forget(session, user, ids, evaluation_ids)
    # deleting a running job's row is its cancellation: its worker's heartbeat and completion find no lease
    session.execute(delete(Job).where(or_(Job.submission_id.in_(ids), Job.evaluation_id.in_(evaluation_ids))))
    session.execute(update(Job).where(Job.owner_id == user.id).values(owner_id=None))  # kept races' jobs
    session.execute(delete(EpisodeResult).where(EpisodeResult.evaluation_id.in_(evaluation_ids)))
    session.execute(delete(Evaluation).where(Evaluation.id.in_(evaluation_ids)))
    session.execute(delete(Submission).where(Submission.id.in_(ids)))
    digests = {s.sha256 for s in submissions}
    used = set(session.scalars(select(Submission.sha256).where(Submission.sha256.in_(digests))))
    erased.blobs = sorted(digests - used)
    session.execute(delete(Blob).where(Blob.sha256.in_(erased.blobs)))
    if user.course is not None:  # the public state stamp: boards and standings drop the student at once
        user.course.updated_at = utcnow()
    session.delete(user)
    session.flush()
    return erased


def write_out(engine: Engine) -> bool:
    """After the deletion's commit, on SQLite: copy the pages it zeroed (secure_delete) into the database
    file and empty the write-ahead log, whose older frames still hold the rows as they were. False if
    readers kept the log from being emptied (then SQLite's later checkpoints overwrite it). PostgreSQL
    keeps deleted rows on disk until its (auto)vacuum reuses the space: nothing to do from here."""
    if engine.dialect.name != "sqlite":
        return True
    with engine.connect() as connection:
        busy, _, _ = connection.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)").one()
    return not busy


def _forget(session: Session, user: User, submission_ids: set[int], evaluation_ids: list[int]) -> None:
    """Every other row that names the student, found from the models' foreign keys to the account,
    their submissions and their evaluations (a table added later included): a row that cannot be
    without it (NOT NULL: their own state in an assignment, their extension, selection and frozen
    final, and so their grade) goes; any other (a race, championship or account they created) loses
    the reference. The tables erased above, with what refers to them, are left to their own steps."""
    named = {User.__table__: [user.id], Submission.__table__: sorted(submission_ids),
             Evaluation.__table__: evaluation_ids}
    for table in Base.metadata.sorted_tables:
        if table in ERASED_IN_STEPS:
            continue
        for key in table.foreign_keys:
            ids = named.get(key.column.table)
            if not ids:
                continue
            rows = key.parent.in_(ids)
            if key.parent.nullable:
                session.execute(update(table).where(rows).values({key.parent.name: None}))
            else:
                session.execute(delete(table).where(rows))


def _erase_races(session: Session, user: User, ids: set[int], erased: Erased) -> None:
    """Delete the student's friendly races no other student raced in and the friendly races with
    their car still to run; scrub the others (championship heats always)."""
    races = {race.id: race for race in session.scalars(select(Race).where(Race.created_by_id == user.id))}
    races.update({race.id: race for race in _races_with(session, ids)})
    for race in races.values():
        mine = [e for e in race.entrants if e["submission_id"] in ids]
        others = [e for e in race.entrants if e["submission_id"] not in ids]
        finished = race.status in (DONE, FAILED)
        if race.championship_id is not None:
            if mine and not finished:
                raise DeletionRefused(f"championship heat (race {race.id}) is still to race with this student's car: "
                                      "delete the student once it is over, or cancel its job")
            _scrub(session, race, ids)
            erased.races_kept += 1
        elif not finished or not any(_student_car(session, e) for e in others):
            session.execute(delete(Job).where(Job.race_id == race.id))
            session.execute(delete(RaceReplay).where(RaceReplay.race_id == race.id))
            session.delete(race)
            erased.races_deleted += 1
        elif mine:
            _scrub(session, race, ids)
            erased.races_kept += 1
    for championship_round in session.scalars(select(ChampionshipRound)):
        if any(i in ids for heat in championship_round.heats for i in heat):
            championship_round.heats = [[-i if i in ids else i for i in heat] for heat in championship_round.heats]


def _races_with(session: Session, ids: set[int]) -> list[Race]:
    """Races with one of these submissions as a car (entrants are JSON: read in Python, a course's few
    thousand races at most)."""
    if not ids:
        return []
    return [race for race in session.scalars(select(Race))
            if any(e["submission_id"] in ids for e in race.entrants)]


def _student_car(session: Session, entrant: dict) -> bool:
    submission = session.get(Submission, entrant["submission_id"]) if entrant["submission_id"] > 0 else None
    return submission is None or submission.owner.role == STUDENT  # a deleted one was a student's


def _scrub(session: Session, race: Race, ids: set[int]) -> None:
    """The race with the student's cars as DELETED: entrants, classification, error, log, replay."""
    names = [car_name(e) for e in race.entrants if e["submission_id"] in ids]
    every_car = [car_name(e) for e in race.entrants]
    race.entrants = [_anonymous(e, ids) for e in race.entrants]
    if race.classification is not None:
        race.classification = [_anonymous(row, ids) for row in race.classification]
    if race.error:
        race.error = _replaced(race.error, names)
    if race.log:
        race.log = _without_cars(race.log, names, every_car)
    replay = session.get(RaceReplay, race.id)
    if replay is not None:
        scrubbed = _scrubbed(json.loads(gzip.decompress(replay.data)), ids, names)
        replay.data = gzip.compress(json.dumps(scrubbed, separators=(",", ":")).encode(), compresslevel=6)


def _anonymous(row: dict, ids: set[int]) -> dict:
    if row["submission_id"] not in ids:
        return row
    return {**row, "submission_id": -row["submission_id"], "name": DELETED, "owner": DELETED}


def _scrubbed(value, ids: set[int], names: list[str]):
    """A replay's JSON with the student's cars anonymous: rows naming their submissions, and their car names."""
    if isinstance(value, dict):
        row = {key: _scrubbed(item, ids, names) for key, item in value.items()}
        return _anonymous(row, ids) if isinstance(row.get("submission_id"), int) else row
    if isinstance(value, list):
        return [_scrubbed(v, ids, names) for v in value]
    return _replaced(value, names) if isinstance(value, str) else value


def _replaced(text: str, names: list[str]) -> str:
    label = car_name({"name": DELETED, "owner": DELETED})
    for name in names:
        text = text.replace(name, label)
    return text


def _without_cars(log: str, names: list[str], every_car: list[str]) -> str:
    """The race log (sections "== car ==\\n...", league.server.jobs.race.race_log) without the sections of `names`."""
    sections, current = [], None
    headers = {f"== {n} ==" for n in every_car}
    for line in log.splitlines(keepends=True):
        if line.rstrip("\n") in headers:
            current = [line]
            sections.append(current)
        elif current is not None:
            current.append(line)
        else:
            sections.append([line])
    dropped = {f"== {n} ==" for n in names}
    return "".join("".join(s) for s in sections if s[0].rstrip("\n") not in dropped)
