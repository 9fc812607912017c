"""SQLAlchemy 2 models. The database is the source of truth for every status a user sees.

Schema changes go through an Alembic migration (league/server/migrations/versions/).
"""
from __future__ import annotations

import secrets
from datetime import datetime, timezone
from typing import Any

from sqlalchemy import (
    JSON, BigInteger, ColumnElement, DateTime, Float, ForeignKey, Index, Integer, LargeBinary, String, Text,
    UniqueConstraint, func, text,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator

# the statuses stored here (submissions, evaluations, jobs, races, rounds) have their home in league.statuses, which
# the client and the pages read too; the server's modules import them from here, beside the models that store them
from league.statuses import DONE, FAILED, PENDING, QUEUED, READY, REJECTED, RUNNING, VALIDATING  # noqa: F401
from league.server.core.clock import utcnow

# roles
INSTRUCTOR, STUDENT, BASELINE = "instructor", "student", "baseline"
DELETED = "deleted student"  # what races and standings show for a deleted student (league.server.course.erasure)

# why a job failed (jobs.failure): it cannot succeed (the handler said so), an error on every attempt, its worker
# stopped heart-beating on every attempt, no worker of this version knows its kind, an instructor cancelled it
CANNOT_SUCCEED, ERROR, WORKER_LOST, UNKNOWN_KIND, CANCELLED = (
    "cannot_succeed", "error", "worker_lost", "unknown_kind", "cancelled")
FAILURES = (CANNOT_SUCCEED, ERROR, WORKER_LOST, UNKNOWN_KIND, CANCELLED)

# job kinds
VALIDATE, EVALUATE, RACE, PROBE = "validate", "evaluate", "race", "probe"
SECRET_PROBE = "secret_probe"  # a submission on its assignments' secret probe sets (league.server.jobs.probe)

# job priorities: a low one is claimed only when no normal one waits
NORMAL, LOW = 0, 1

# who sees a course's boards (courses.board_visibility; league.server.course.privacy): anyone, its logged-in users,
# its instructors
VISIBILITY_PUBLIC, VISIBILITY_MEMBERS, VISIBILITY_INSTRUCTORS = "public", "members", "instructors"
BOARD_VISIBILITIES = (VISIBILITY_PUBLIC, VISIBILITY_MEMBERS, VISIBILITY_INSTRUCTORS)

# which of an assignment's tracks an evaluation drove (evaluations.track): its public ones (`seed`: the public
# board, reproducible with `league evaluate`) or its private test's (`private_seed`: finals, the private board)
PUBLIC_TRACKS, PRIVATE_TRACKS = "public", "private"


class UTCDateTime(TypeDecorator):
    """Aware UTC datetimes on every backend (SQLite keeps no time zone: stored naive, read back as UTC)."""

    impl = DateTime
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Any) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime given to a UTC column")
        return value.astimezone(timezone.utc).replace(tzinfo=None)

    def process_result_value(self, value: datetime | None, dialect: Any) -> datetime | None:
        return None if value is None else value.replace(tzinfo=timezone.utc)


class Base(DeclarativeBase):
    type_annotation_map = {datetime: UTCDateTime(), dict[str, Any]: JSON(), list[Any]: JSON()}


class Course(Base):
    """A class of students and its assignments (the oldest is the default one: /api/settings/evaluation)."""

    __tablename__ = "courses"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(100), unique=True)
    # who sees its boards; the server default is what courses older than the setting were (migration 0012)
    board_visibility: Mapped[str] = mapped_column(String(20), default=VISIBILITY_MEMBERS,
                                                  server_default=VISIBILITY_PUBLIC)
    # keyed the "Student N" pseudonyms until migration 0020 gave each user a random one (users.pseudonym);
    # unused since, kept as dropping a column referred to by foreign keys copies the table on SQLite
    pseudonym_key: Mapped[int] = mapped_column(BigInteger, nullable=True, default=lambda: secrets.randbits(62))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow, onupdate=utcnow)


class Assignment(Base):
    """A piece of coursework: its tracks, its upload window and its private test.

    The public board ranks on `seed` (shown: `league evaluate FILE --seed S` reproduces it); at each
    student's own close time their final submission is evaluated on `private_seed` (drawn by the
    server, never shown before `published_at`) with the same episodes and options. Uploads are
    open from `opens_at` (None: at once) to the student's due time (`due_at`, or their extension;
    None: no deadline), then late until `late_until` (their score times `late_penalty`).
    """

    __tablename__ = "assignments"
    __table_args__ = (UniqueConstraint("course_id", "name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    name: Mapped[str] = mapped_column(String(100))
    description: Mapped[str] = mapped_column(Text, default="")
    seed: Mapped[int] = mapped_column(BigInteger)
    episodes: Mapped[int] = mapped_column(Integer)
    env_options: Mapped[dict[str, Any]] = mapped_column(default=dict)
    private_seed: Mapped[int] = mapped_column(BigInteger)
    opens_at: Mapped[datetime | None] = mapped_column(default=None)
    due_at: Mapped[datetime | None] = mapped_column(default=None)
    late_until: Mapped[datetime | None] = mapped_column(default=None)
    late_penalty: Mapped[float | None] = mapped_column(Float, default=None)  # a late final's score factor
    daily_quota: Mapped[int | None] = mapped_column(Integer, default=None)  # uploads per student per UTC day
    auto_publish: Mapped[bool] = mapped_column(default=False)
    published_at: Mapped[datetime | None] = mapped_column(default=None)
    # the grading rubric (league.server.course.grading.read_rubric reads it); None until the instructor sets one
    rubric: Mapped[dict[str, Any] | None] = mapped_column(JSON, default=None)
    # the course's automatic assignment (made with the course, named "default"): it takes no more uploads
    # once the course has an assignment of its instructors', unless they keep it open (assignments.retired)
    automatic: Mapped[bool] = mapped_column(default=False, server_default=text("false"))
    keep_open: Mapped[bool] = mapped_column(default=False, server_default=text("false"))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow, onupdate=utcnow)

    def evaluation_settings(self) -> dict[str, Any]:
        """The public tracks' settings."""
        return {"seed": self.seed, "episodes": self.episodes, "env_options": dict(self.env_options)}

    def private_settings(self) -> dict[str, Any]:
        return {"seed": self.private_seed, "episodes": self.episodes, "env_options": dict(self.env_options)}


class StudentAssignment(Base):
    """A student's own state in an assignment, one row made when first needed: the extension an
    instructor gave, the submission they selected, and their final (league.server.course.assignments).

    At their close time the final is frozen (`final_at`, the close time) with its candidates
    (`final_candidates`: the ids of their uploads then, rejected ones aside); it is decided
    (`final_decided_at`) once each candidate is validated and evaluated on the public tracks,
    whatever the queue was doing at the close time. Then `final_submission_id` is what the private
    test evaluates (None: no candidate made it) and `final_evaluation_id` that evaluation.
    `published_evaluation_id` is the private result the grade had when the assignment was
    published (no foreign key: a record), so that a grade can say it changed since."""

    __tablename__ = "student_assignments"
    __table_args__ = (UniqueConstraint("assignment_id", "user_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id"))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    extension_due_at: Mapped[datetime | None] = mapped_column(default=None)
    selected_submission_id: Mapped[int | None] = mapped_column(ForeignKey("submissions.id"), default=None)
    final_at: Mapped[datetime | None] = mapped_column(default=None)
    final_submission_id: Mapped[int | None] = mapped_column(ForeignKey("submissions.id"), default=None)
    final_evaluation_id: Mapped[int | None] = mapped_column(ForeignKey("evaluations.id"), default=None)
    final_candidates: Mapped[list[Any] | None] = mapped_column(JSON, default=None)
    final_decided_at: Mapped[datetime | None] = mapped_column(default=None)
    published_evaluation_id: Mapped[int | None] = mapped_column(Integer, default=None)


class User(Base):
    """An instructor, a student, or the `baselines` account that owns the bundled agents (no token)."""

    __tablename__ = "users"
    # NULLs differ on both backends: many students without an id, none sharing one
    __table_args__ = (Index("uq_users_course_student_id", "course_id", "student_id", unique=True),
                      Index("uq_users_course_display_name", "course_id", "display_name", unique=True),
                      Index("uq_users_course_pseudonym", "course_id", "pseudonym", unique=True))

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(100), unique=True)
    role: Mapped[str] = mapped_column(String(20))
    course_id: Mapped[int | None] = mapped_column(ForeignKey("courses.id"))
    # how gradebook exports (Canvas, Moodle) identify the student; from the roster, optional
    email: Mapped[str | None] = mapped_column(String(254), default=None)
    student_id: Mapped[str | None] = mapped_column(String(64), default=None)  # Canvas's SIS User ID, Moodle's ID number
    # Canvas's own ids of the student, from its gradebook export (league.server.course.roster): the Canvas user
    # ID and the SIS Login ID, which Canvas's gradebook import matches students by before their names
    canvas_id: Mapped[str | None] = mapped_column(String(64), default=None)
    sis_login_id: Mapped[str | None] = mapped_column(String(254), default=None)
    # what public boards show instead of the name (league.server.course.privacy); unique in the course
    display_name: Mapped[str | None] = mapped_column(String(100), default=None)
    # "Student N" on public boards (league.server.course.privacy): drawn at random when the account is made
    # (crud.add_user; migration 0020 for older ones), unique in the course; None: no course
    pseudonym: Mapped[int | None] = mapped_column(Integer, default=None)
    token_hash: Mapped[str | None] = mapped_column(String(64), unique=True)  # sha256 hex of the bearer token
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    revoked_at: Mapped[datetime | None] = mapped_column(default=None, index=True)  # indexed: the state stamp
    # the submission that races in championships; None: the latest ready one
    active_submission_id: Mapped[int | None] = mapped_column(Integer, default=None)  # no FK: users <-> submissions

    course: Mapped[Course | None] = relationship(lazy="joined")

    @property
    def active(self) -> bool:
        return self.revoked_at is None


class Blob(Base):
    """A submitted file's bytes, by sha256: workers on other machines fetch models from here into
    their own store, so they need only the database and the queue, no shared filesystem."""

    __tablename__ = "blobs"

    sha256: Mapped[str] = mapped_column(String(64), primary_key=True)
    size: Mapped[int] = mapped_column(Integer)
    data: Mapped[bytes] = mapped_column(LargeBinary)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)


class Submission(Base):
    """An uploaded model file; the file itself lives in the content-addressed store (by sha256)."""

    __tablename__ = "submissions"
    __table_args__ = (Index("ix_submissions_owner_created", "owner_id", "created_at"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    owner_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    # every row has one (crud.create_submission); nullable in the schema only, as evaluations.result_key
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id"), nullable=True, index=True)
    late: Mapped[bool] = mapped_column(default=False, server_default=text("false"))  # after the owner's due time
    name: Mapped[str] = mapped_column(String(100))
    filename: Mapped[str] = mapped_column(String(255))
    kind: Mapped[str] = mapped_column(String(20))  # "onnx" or "torchscript", from the file name
    sha256: Mapped[str] = mapped_column(String(64), index=True)
    size: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(20), default=PENDING, index=True)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    log: Mapped[str | None] = mapped_column(Text, default=None)  # sandbox output of the validation, truncated
    obs_dim: Mapped[int | None] = mapped_column(Integer, default=None)
    public: Mapped[bool] = mapped_column(default=False)
    # its actions on the probe set named by probe_key (league.validation.probes), float32 (64, 2) bytes;
    # None with a key: the model failed on it (why: its log); no key: not probed yet (league.server.course.integrity)
    probe_key: Mapped[str | None] = mapped_column(String(16), default=None)
    probe_actions: Mapped[bytes | None] = mapped_column(LargeBinary, default=None, deferred=True)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow, onupdate=utcnow)

    owner: Mapped[User] = relationship(lazy="joined")


class SubmissionProbe(Base):
    """A submission's actions on an assignment's secret probe set (league.validation.probes), named by
    its key: float32 (64, 2) bytes, or None with `error` when the model failed on it. Read by the
    integrity report only: no answer a student can obtain shows a row (they derive from the private
    tracks). Deleted with their submission (ON DELETE CASCADE)."""

    __tablename__ = "submission_probes"
    __table_args__ = (UniqueConstraint("submission_id", "probe_key"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id", ondelete="CASCADE"), index=True)
    probe_key: Mapped[str] = mapped_column(String(16))
    actions: Mapped[bytes | None] = mapped_column(LargeBinary, default=None)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)


class Evaluation(Base):
    """One `metrics_run` of a submission with an assignment's settings; re-runs add new rows.

    `track` PRIVATE_TRACKS: the assignment's private test of a final (league.server.course.assignments); no answer
    a student can obtain shows one before the assignment is published.

    `result_key` (league.evaluation.result_key: the settings and the simulator's version) is what
    its results compare by: the requested one while it waits, the one its worker's simulator
    produced once done. Boards rank only results of their course's current key (league.server.course.results).
    """

    __tablename__ = "evaluations"
    __table_args__ = (Index("ix_evaluations_key_status_submission", "result_key", "status", "submission_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"), index=True)
    course_id: Mapped[int | None] = mapped_column(ForeignKey("courses.id"))
    assignment_id: Mapped[int | None] = mapped_column(ForeignKey("assignments.id"), default=None)  # whose settings
    track: Mapped[str] = mapped_column(String(10), default=PUBLIC_TRACKS, server_default=PUBLIC_TRACKS)
    settings: Mapped[dict[str, Any]] = mapped_column()  # {"seed", "episodes", "env_options"} as requested
    status: Mapped[str] = mapped_column(String(20), default=QUEUED)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    log: Mapped[str | None] = mapped_column(Text, default=None)
    completed: Mapped[int | None] = mapped_column(Integer, default=None)
    episodes_total: Mapped[int | None] = mapped_column(Integer, default=None)
    mean_return: Mapped[float | None] = mapped_column(Float, default=None)
    mean_steps: Mapped[float | None] = mapped_column(Float, default=None)
    mean_speed: Mapped[float | None] = mapped_column(Float, default=None)
    result_settings: Mapped[dict[str, Any] | None] = mapped_column(JSON, default=None)  # metrics_run's record
    # every row has one (crud.create_evaluation); nullable in the schema only: SQLite cannot make an existing
    # column NOT NULL without copying the table, which the foreign keys to it forbid (migration 0007)
    result_key: Mapped[str] = mapped_column(String(16), nullable=True)
    # {"physics", "track_format", "package"} once done
    versions: Mapped[dict[str, Any] | None] = mapped_column(JSON, default=None)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(default=None)

    # loaded only when read: status answers and listings carry no episodes (crud.episode_page pages them)
    episodes: Mapped[list[EpisodeResult]] = relationship(order_by="EpisodeResult.index", lazy="select")


def private_test() -> ColumnElement[bool]:
    """Whether a job (outer-joined to its evaluation) is the private test of a final: the league's own
    job, not its owner's (no in-flight limit, no turn among their jobs; league.server.course.assignments)."""
    return func.coalesce(Evaluation.track, "") == PRIVATE_TRACKS


class EpisodeResult(Base):
    __tablename__ = "episode_results"
    __table_args__ = (UniqueConstraint("evaluation_id", "index"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    evaluation_id: Mapped[int] = mapped_column(ForeignKey("evaluations.id"))
    index: Mapped[int] = mapped_column(Integer)
    seed: Mapped[int] = mapped_column(BigInteger)  # episode seeds are uint32
    steps: Mapped[int] = mapped_column(Integer)
    episode_return: Mapped[float] = mapped_column(Float)
    mean_speed: Mapped[float] = mapped_column(Float)
    outcome: Mapped[str] = mapped_column(String(20))
    reason: Mapped[str | None] = mapped_column(Text, default=None)


class Job(Base):
    """A unit of work for the queue, with its lease: the queue only carries the job id.

    A worker claims a queued job (status -> running, its worker_id, attempts + 1), heart-beats
    while it works, and writes the results in the same transaction that marks the job done,
    only if it still holds the lease. The reaper gives jobs whose heartbeat stopped to another
    worker (fishtest's dead-task scavenging). `owner_id` is whose job it is: the queue serves
    owners in turn, and limits how many jobs each has waiting. `priority` LOW (the re-evaluations
    a settings change queues) waits until no NORMAL job does, and counts in no owner's limit.
    """

    __tablename__ = "jobs"
    __table_args__ = (Index("ix_jobs_status_heartbeat", "status", "heartbeat_at"),
                      # an owner's jobs by status, in their turns' order (leases.first_turns)
                      Index("ix_jobs_status_owner_turn", "status", "owner_id", "priority", "id"),
                      Index("ix_jobs_kind_finished", "kind", "finished_at"))  # the state stamp

    id: Mapped[int] = mapped_column(primary_key=True)
    kind: Mapped[str] = mapped_column(String(20))
    owner_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", name="fk_jobs_owner_id_users"), default=None)
    submission_id: Mapped[int | None] = mapped_column(ForeignKey("submissions.id"), index=True)
    evaluation_id: Mapped[int | None] = mapped_column(ForeignKey("evaluations.id"))
    race_id: Mapped[int | None] = mapped_column(ForeignKey("races.id"), index=True, default=None)
    status: Mapped[str] = mapped_column(String(20), default=QUEUED)
    priority: Mapped[int] = mapped_column(Integer, default=NORMAL, server_default=text("0"))  # NORMAL or LOW
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    max_attempts: Mapped[int] = mapped_column(Integer, default=3)
    worker_id: Mapped[str | None] = mapped_column(String(100), default=None)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    failure: Mapped[str | None] = mapped_column(String(20), default=None)  # one of FAILURES once failed
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    enqueued_at: Mapped[datetime] = mapped_column(default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(default=None)
    heartbeat_at: Mapped[datetime | None] = mapped_column(default=None)
    finished_at: Mapped[datetime | None] = mapped_column(default=None)


# the queued jobs in the order of their ids, per priority and kind (validations, evaluations), and per
# priority for the other kinds: a claim reads the first ones (league.server.jobs.leases.first_turns),
# never every queued job
QUEUED_OTHER_KIND = (Job.status == QUEUED) & Job.kind.not_in((VALIDATE, EVALUATE))
Index("ix_jobs_queued_kind", Job.priority, Job.kind, Job.id,
      postgresql_where=Job.status == QUEUED, sqlite_where=Job.status == QUEUED)
Index("ix_jobs_queued_other", Job.priority, Job.id, postgresql_where=QUEUED_OTHER_KIND, sqlite_where=QUEUED_OTHER_KIND)


class Championship(Base):
    """A term's competition: rounds of heats on new tracks, points by a table, OpenSkill ratings."""

    __tablename__ = "championships"

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int | None] = mapped_column(ForeignKey("courses.id"), index=True)
    # its rounds race each student's final choice of this assignment; none: their active submission
    assignment_id: Mapped[int | None] = mapped_column(ForeignKey("assignments.id"), default=None)
    name: Mapped[str] = mapped_column(String(100))
    env_options: Mapped[dict[str, Any]] = mapped_column(default=dict)
    heat_size: Mapped[int] = mapped_column(Integer)
    points: Mapped[list[Any]] = mapped_column()
    include_baselines: Mapped[bool] = mapped_column(default=True)
    seed: Mapped[int] = mapped_column(BigInteger)  # the rounds' heat draws (tracks: drawn secretly per round)
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)

    rounds: Mapped[list[ChampionshipRound]] = relationship(order_by="ChampionshipRound.number", lazy="selectin")


class ChampionshipRound(Base):
    """One round: its track seed (drawn secretly, shown once the round is over) and its heats (lists
    of submission ids), fixed when it is created, so the round can be raced again from what is
    stored. Its status follows from its heats' races."""

    __tablename__ = "championship_rounds"
    __table_args__ = (UniqueConstraint("championship_id", "number"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    championship_id: Mapped[int] = mapped_column(ForeignKey("championships.id"))
    number: Mapped[int] = mapped_column(Integer)
    track_seed: Mapped[int] = mapped_column(BigInteger)
    heats: Mapped[list[Any]] = mapped_column()  # [[submission_id, ...], ...]
    created_at: Mapped[datetime] = mapped_column(default=utcnow)

    races: Mapped[list[Race]] = relationship(order_by="Race.heat", lazy="selectin")

    @property
    def status(self) -> str:
        """pending, running, done or failed (once no heat is left to race and one failed): what its
        heats' races are."""
        statuses = [r.status for r in self.races]
        if statuses and all(s == DONE for s in statuses):
            return DONE
        if not any(s in (PENDING, RUNNING) for s in statuses):
            return FAILED
        if any(s in (RUNNING, DONE, FAILED) for s in statuses):
            return RUNNING
        return PENDING


class Race(Base):
    """A race (friendly, or a championship heat): entrants, seed and options in; classification out.

    `entrants` keeps each car's submission id, name and owner as they were when the race was
    created; the replay (the toolkit's JSON, gzip-compressed) is in RaceReplay.
    """

    __tablename__ = "races"
    __table_args__ = (Index("ix_races_creator_created", "created_by_id", "created_at"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int | None] = mapped_column(ForeignKey("courses.id"))
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    championship_id: Mapped[int | None] = mapped_column(ForeignKey("championships.id"), index=True)
    round_id: Mapped[int | None] = mapped_column(ForeignKey("championship_rounds.id"), index=True)
    heat: Mapped[int | None] = mapped_column(Integer)  # 1-based, within its round
    seed: Mapped[int] = mapped_column(BigInteger)
    env_options: Mapped[dict[str, Any]] = mapped_column(default=dict)
    entrants: Mapped[list[Any]] = mapped_column()  # [{"submission_id", "name", "owner"}], car i = entrant i
    status: Mapped[str] = mapped_column(String(20), default=PENDING, index=True)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    log: Mapped[str | None] = mapped_column(Text, default=None)  # what the cars' sandboxes printed, truncated
    classification: Mapped[list[Any] | None] = mapped_column(JSON, default=None)
    # the simulator's and package's, once raced
    versions: Mapped[dict[str, Any] | None] = mapped_column(JSON, default=None)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(default=None)
    finished_at: Mapped[datetime | None] = mapped_column(default=None)


class RaceReplay(Base):
    __tablename__ = "race_replays"

    race_id: Mapped[int] = mapped_column(ForeignKey("races.id"), primary_key=True)
    data: Mapped[bytes] = mapped_column(LargeBinary)  # gzip of the replay JSON (a 10-car race: ~60 KB)


class AuditEvent(Base):
    """Who did what to whom (league.server.course.audit): instructors' actions and admin commands.

    `actor_id` has no foreign key: the record outlives the accounts it names. `actor_name` is the
    instructor's (an admin command's: "league CLI"); a deleted student's name is never kept here.
    """

    __tablename__ = "audit_events"

    id: Mapped[int] = mapped_column(primary_key=True)
    at: Mapped[datetime] = mapped_column(default=utcnow, index=True)
    course_id: Mapped[int | None] = mapped_column(Integer, default=None, index=True)
    actor_id: Mapped[int | None] = mapped_column(Integer, default=None)
    actor_name: Mapped[str] = mapped_column(String(100))
    action: Mapped[str] = mapped_column(String(40))
    target_kind: Mapped[str] = mapped_column(String(20))
    target_id: Mapped[int | None] = mapped_column(BigInteger, default=None)
    details: Mapped[dict[str, Any]] = mapped_column(default=dict)


API_PROCESS, WORKER_PROCESS = "api", "worker"


class WorkerProcess(Base):
    """A running league process, beating every few seconds: a `league worker` (serve's own included)
    or an API process (`kind`). /api/health says whether queued jobs have a worker to run them;
    `league migrate` refuses while processes of another version run. A process removes its row when
    it stops; the rows of processes that died expire (league.server.jobs.registry)."""

    __tablename__ = "workers"

    id: Mapped[int] = mapped_column(primary_key=True)
    kind: Mapped[str] = mapped_column(String(10), default=WORKER_PROCESS, server_default=WORKER_PROCESS)
    host: Mapped[str] = mapped_column(String(255))
    pid: Mapped[int] = mapped_column(Integer)
    version: Mapped[str] = mapped_column(String(50))  # microracer-league's
    started_at: Mapped[datetime] = mapped_column(default=utcnow)
    heartbeat_at: Mapped[datetime] = mapped_column(default=utcnow, index=True)
