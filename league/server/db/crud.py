"""Database functions (keyword-only arguments). They add and flush; callers commit."""
from __future__ import annotations

import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import Connection, Row, bindparam, case, delete, func, select, update
from sqlalchemy.dialects.postgresql import insert as postgresql_insert
from sqlalchemy.dialects.sqlite import insert as sqlite_insert
from sqlalchemy.orm import Session

from league.server.course.accounts import clean_email, clean_name, clean_student_id
from league.server.db.models import (
    BASELINE, DONE, EVALUATE, FAILED, NORMAL, PUBLIC_TRACKS, QUEUED, RACE, READY, REJECTED, RUNNING, STUDENT,
    VALIDATE, VISIBILITY_MEMBERS, Assignment, Blob, Championship, ChampionshipRound, Course, EpisodeResult, Evaluation,
    Job, Race, StudentAssignment, Submission, User, private_test, utcnow,
)
from league.server.core.security import hash_token, new_token
from league.server.course.privacy import clean_display_name, draw_pseudonym

DEFAULT_COURSE = "default"
DEFAULT_ASSIGNMENT = "default"  # a new course's first assignment (migration 0010 made one per course)
BASELINES_USER = "baselines"
QUOTA_WINDOW = timedelta(hours=24)
NOT_COUNTED = (REJECTED, FAILED)  # a student's quota is not eaten by uploads the league refused or lost
NOT_KEPT = (REJECTED,)  # a rejected upload's bytes are deleted (it can never race or be evaluated)


class InvalidAccount(ValueError):
    """An invalid or taken name, email or student id (message shown to the caller)."""


class AccountTaken(InvalidAccount):
    """A name (unique in the league), or an email or student id (unique in a course), already in use."""


# --------------------------------------------------------------------------- courses


def get_or_create_course(session: Session, *, name: str, evaluation: dict[str, Any],
                         board_visibility: str | None = None) -> Course:
    """The course named `name`; a new one takes `board_visibility` (None: members) and gets its default
    assignment with the `evaluation` settings."""
    course = session.scalar(select(Course).where(Course.name == name))
    if course is None:
        course = Course(name=name, board_visibility=board_visibility or VISIBILITY_MEMBERS)
        session.add(course)
        session.flush()
        create_assignment(session, course=course, name=DEFAULT_ASSIGNMENT, seed=evaluation["seed"],
                          episodes=evaluation["episodes"], env_options=evaluation["env_options"], automatic=True)
    return course


def first_course(session: Session) -> Course | None:
    return session.scalar(select(Course).order_by(Course.id).limit(1))


def set_evaluation_settings(session: Session, *, assignment: Assignment, seed: int, episodes: int,
                            env_options: dict[str, Any]) -> Assignment:
    assignment.seed, assignment.episodes, assignment.env_options = seed, episodes, dict(env_options)
    session.flush()
    return assignment


# --------------------------------------------------------------------------- assignments


def create_assignment(session: Session, *, course: Course, name: str, seed: int, episodes: int,
                      env_options: dict[str, Any], **fields: Any) -> Assignment:
    """A new assignment; its private seed drawn here (secrets: nothing a student reads predicts it)."""
    assignment = Assignment(course_id=course.id, name=name, seed=seed, episodes=episodes,
                            env_options=dict(env_options), private_seed=secrets.randbits(32), **fields)
    session.add(assignment)
    session.flush()
    return assignment


def all_assignments(session: Session) -> list[Assignment]:
    return list(session.scalars(select(Assignment).order_by(Assignment.id)))


def course_assignments(session: Session, *, course_id: int) -> list[Assignment]:
    return list(session.scalars(select(Assignment).where(Assignment.course_id == course_id).order_by(Assignment.id)))


def has_own_assignments(session: Session, *, course_id: int) -> bool:
    """Whether the course has an assignment its instructors made (not its automatic one)."""
    return session.scalar(select(Assignment.id).where(Assignment.course_id == course_id,
                                                      Assignment.automatic.is_(False)).limit(1)) is not None


def default_assignment(session: Session, *, course_id: int) -> Assignment | None:
    """The course's oldest assignment: the one /api/settings/evaluation and /api/leaderboard show."""
    return session.scalar(select(Assignment).where(Assignment.course_id == course_id)
                          .order_by(Assignment.id).limit(1))


def student_assignment(session: Session, *, assignment_id: int, user_id: int,
                       create: bool = False) -> StudentAssignment | None:
    """The student's row of the assignment (made, when `create`, on first need)."""
    row = session.scalar(select(StudentAssignment).where(StudentAssignment.assignment_id == assignment_id,
                                                         StudentAssignment.user_id == user_id))
    if row is None and create:
        row = StudentAssignment(assignment_id=assignment_id, user_id=user_id)
        session.add(row)
        session.flush()
    return row


def student_assignments(session: Session, *, assignment_id: int) -> dict[int, StudentAssignment]:
    """The assignment's student rows, by user id."""
    return {row.user_id: row for row in session.scalars(
        select(StudentAssignment).where(StudentAssignment.assignment_id == assignment_id))}


def uploads_since(session: Session, *, owner_id: int, assignment_id: int, since: datetime) -> int:
    """The owner's uploads to the assignment since `since` that count in a quota."""
    return session.scalar(select(func.count(Submission.id)).where(
        Submission.owner_id == owner_id, Submission.assignment_id == assignment_id, Submission.created_at >= since,
        Submission.status.not_in(NOT_COUNTED))) or 0


# --------------------------------------------------------------------------- users


def check_user_name(session: Session, *, name: str) -> str:
    """The name cleaned (accounts.clean_name), if no account holds it yet."""
    try:
        name = clean_name(name)
    except ValueError as error:
        raise InvalidAccount(str(error)) from None
    if session.scalar(select(User.id).where(User.name == name)) is not None:
        raise AccountTaken(f"user name {name!r} is already taken")
    return name


def check_identifiers(session: Session, *, course: Course | None, email: str | None,
                      student_id: str | None) -> tuple[str | None, str | None]:
    """The email and student id cleaned, if no other account of the course holds them."""
    try:
        email, student_id = clean_email(email or ""), clean_student_id(student_id or "")
    except ValueError as error:
        raise InvalidAccount(str(error)) from None
    course_id = course.id if course else None
    for label, column, value in (("email", User.email, email), ("student id", User.student_id, student_id)):
        holder = value and session.scalar(select(User.name).where(User.course_id == course_id, column == value))
        if holder:
            raise AccountTaken(f"the {label} {value!r} is already {holder!r}'s")
    return email, student_id


def create_user(session: Session, *, name: str, role: str, course: Course | None, created_by: User | None = None,
                with_token: bool = True, email: str | None = None,
                student_id: str | None = None) -> tuple[User, str | None]:
    """Add a user; return it with its token (shown once, stored hashed)."""
    name = check_user_name(session, name=name)
    email, student_id = check_identifiers(session, course=course, email=email, student_id=student_id)
    user, token = add_user(session, name=name, role=role, course=course, created_by=created_by, with_token=with_token,
                           email=email, student_id=student_id)
    session.flush()
    return user, token


def add_user(session: Session, *, name: str, role: str, course: Course | None, created_by: User | None,
             with_token: bool, email: str | None, student_id: str | None, canvas_id: str | None = None,
             sis_login_id: str | None = None) -> tuple[User, str | None]:
    """Add a user whose values the caller has cleaned and found free (a roster checks them all at once);
    no flush: a roster adds its students in one round trip. A course's user gets its pseudonym."""
    token = new_token() if with_token else None
    user = User(name=name, role=role, course_id=course.id if course else None, email=email, student_id=student_id,
                canvas_id=canvas_id, sis_login_id=sis_login_id,
                token_hash=hash_token(token) if token else None, created_by_id=created_by.id if created_by else None,
                pseudonym=new_pseudonym(session, course_id=course.id) if course else None)
    session.add(user)
    return user, token


def new_pseudonym(session: Session, *, course_id: int) -> int:
    """A random pseudonym number no user of the course has, the ones not flushed yet (a roster's) included."""
    pending = {user.pseudonym for user in session.new if isinstance(user, User) and user.course_id == course_id}

    def taken(number: int) -> bool:
        with session.no_autoflush:
            return number in pending or session.scalar(
                select(User.id).where(User.course_id == course_id, User.pseudonym == number).limit(1)) is not None
    return draw_pseudonym(taken)


def pseudonyms(session: Session, *, course_id: int) -> dict[int, int]:
    """user id -> pseudonym number, of the course's users."""
    return dict(session.execute(select(User.id, User.pseudonym).where(User.course_id == course_id,
                                                                      User.pseudonym.is_not(None))).all())


def user_by_token(session: Session, *, token: str) -> User | None:
    return session.scalar(select(User).where(User.token_hash == hash_token(token)))


def user_by_name(session: Session, *, name: str) -> User | None:
    return session.scalar(select(User).where(User.name == name))


def course_users(session: Session, *, course_id: int | None) -> list[User]:
    return list(session.scalars(select(User).where(User.course_id == course_id).order_by(User.id)))


def set_display_name(session: Session, *, user: User, display_name: str | None) -> User:
    """Give the user a display name (privacy.clean_display_name), unless it is the name or the display
    name of another account of the course, or of an account of no course (the baselines', shown on every
    board); None removes it. Other courses' accounts are never looked at: their boards are theirs, and
    "taken" must not tell a student who is enrolled elsewhere. One message for both: it names nobody."""
    try:
        display_name = clean_display_name(display_name)
    except ValueError as error:
        raise InvalidAccount(str(error).replace("the name", "the display name", 1)) from None
    if display_name is not None:
        folded = func.lower(display_name)  # the database's lower() on both sides: exact matches on any backend
        neighbours = (User.course_id == user.course_id) | User.course_id.is_(None)
        taken = session.scalar(select(User.id).where(User.id != user.id, neighbours, (
            func.lower(User.name) == folded) | (func.lower(User.display_name) == folded)).limit(1))
        if taken is not None:
            raise AccountTaken(f"the display name {display_name!r} is taken: choose another")
    user.display_name = display_name
    session.flush()
    return user


def display_names(session: Session, *, course_id: int) -> dict[int, str]:
    """user id -> display name, of the course's users who chose one."""
    return dict(session.execute(select(User.id, User.display_name).where(User.course_id == course_id,
                                                                         User.display_name.is_not(None))).all())


def revoke_user(session: Session, *, user: User) -> User:
    if user.revoked_at is None:
        user.revoked_at = utcnow()
    session.flush()
    return user


def reissue_token(session: Session, *, user: User) -> str:
    token = new_token()
    user.token_hash, user.revoked_at = hash_token(token), None
    session.flush()
    return token


# --------------------------------------------------------------------------- quotas


@dataclass
class QuotaUsage:
    used: int
    limit: int
    next_free_at: datetime | None  # when the oldest counted submission leaves the window

    @property
    def exhausted(self) -> bool:
        return self.used >= self.limit


def lock_user(session: Session, *, user_id: int) -> bool:
    """Hold the user's row until the transaction ends (PostgreSQL: a row lock; SQLite: the database's
    write lock), so that checking a quota and using it are one step for concurrent requests.
    False if the user is gone (deleted meanwhile: league.server.course.erasure)."""
    return bool(session.execute(update(User).where(User.id == user_id).values(id=User.id)).rowcount)


def jobs_in_flight(session: Session, *, owner_id: int) -> int:
    """The owner's jobs waiting or running, but the league's own: re-evaluations it queued at low priority,
    and the private tests of their finals (how many and how long is none of the student's business)."""
    return session.scalar(
        select(func.count(Job.id)).outerjoin(Evaluation, Job.evaluation_id == Evaluation.id)
        .where(Job.owner_id == owner_id, Job.priority == NORMAL, Job.status.in_((QUEUED, RUNNING)),
               ~private_test())) or 0


def quota_usage(session: Session, *, owner: User, limit: int, now: datetime | None = None) -> QuotaUsage:
    now = now or utcnow()
    counted = select(Submission.created_at).where(
        Submission.owner_id == owner.id, Submission.created_at > now - QUOTA_WINDOW,
        Submission.status.not_in(NOT_COUNTED)).order_by(Submission.created_at)
    times = list(session.scalars(counted))
    next_free = times[len(times) - limit] + QUOTA_WINDOW if len(times) >= limit > 0 else None
    return QuotaUsage(len(times), limit, next_free)


# --------------------------------------------------------------------------- submissions, evaluations, jobs


def save_blob(session: Session, *, sha256: str, data: bytes) -> None:
    """Keep a file's bytes once: an upload of the same bytes at the same moment finds them kept."""
    insert = {"sqlite": sqlite_insert, "postgresql": postgresql_insert}[session.get_bind().dialect.name]
    session.execute(insert(Blob).values(sha256=sha256, size=len(data), data=data, created_at=utcnow())
                    .on_conflict_do_nothing(index_elements=["sha256"]))


def forget_blob_unless_used(session: Session, *, sha256: str) -> bool:
    """Delete a file's bytes when no submission but rejected ones refers to them; True if deleted."""
    used = session.scalar(select(func.count(Submission.id)).where(Submission.sha256 == sha256,
                                                                  Submission.status.not_in(NOT_KEPT)))
    if used:
        return False
    session.execute(delete(Blob).where(Blob.sha256 == sha256))
    return True


def kept_blobs(session: Session, *, sha256s: list[str] | None = None) -> set[str]:
    """The digests whose bytes are kept (of `sha256s`, or all)."""
    query = select(Blob.sha256)
    if sha256s is not None:
        query = query.where(Blob.sha256.in_(sha256s))
    return set(session.scalars(query))


def blob_data(session: Session, *, sha256: str) -> bytes | None:
    blob = session.get(Blob, sha256)
    return None if blob is None else blob.data


def create_submission(session: Session, *, owner: User, name: str, filename: str, kind: str, sha256: str, size: int,
                      max_attempts: int, assignment: Assignment | None = None, late: bool = False,
                      created_at: datetime | None = None) -> tuple[Submission, Job]:
    """A new submission of `assignment` (default: the default one of its owner's course, or of the
    first course for the baselines) and its validation job (both queued in this transaction)."""
    assignment = assignment or default_assignment(session, course_id=(owner.course or first_course(session)).id)
    submission = Submission(owner_id=owner.id, assignment_id=assignment.id, name=name, filename=filename, kind=kind,
                            sha256=sha256, size=size, late=late, created_at=created_at or utcnow())
    session.add(submission)
    session.flush()
    job = create_job(session, kind=VALIDATE, owner_id=owner.id, submission_id=submission.id,
                     max_attempts=max_attempts)
    return submission, job


def create_job(session: Session, *, kind: str, owner_id: int | None, submission_id: int | None = None,
               evaluation_id: int | None = None, race_id: int | None = None, max_attempts: int = 3,
               priority: int = NORMAL) -> Job:
    job = Job(kind=kind, owner_id=owner_id, submission_id=submission_id, evaluation_id=evaluation_id,
              race_id=race_id, status=QUEUED, max_attempts=max_attempts, priority=priority)
    session.add(job)
    session.flush()
    return job


def create_evaluation(session: Session, *, submission: Submission, assignment: Assignment, settings: dict[str, Any],
                      result_key: str, max_attempts: int, priority: int = NORMAL,
                      track: str = PUBLIC_TRACKS) -> tuple[Evaluation, Job]:
    evaluation = Evaluation(submission_id=submission.id, course_id=assignment.course_id, assignment_id=assignment.id,
                            track=track, settings=settings, result_key=result_key, status=QUEUED)
    session.add(evaluation)
    session.flush()
    job = create_job(session, kind=EVALUATE, owner_id=submission.owner_id, submission_id=submission.id,
                     evaluation_id=evaluation.id, max_attempts=max_attempts, priority=priority)
    return evaluation, job


def latest_evaluation(session: Session, *, submission_id: int, result_key: str | None,
                      course_id: int | None = None) -> Evaluation | None:
    """The submission's newest public evaluation of `result_key` if it has one, else its newest public one
    (of `course_id`'s assignments only, when given: a baseline's, which each course evaluates for itself)."""
    query = select(Evaluation).where(Evaluation.submission_id == submission_id, Evaluation.track == PUBLIC_TRACKS)
    if course_id is not None:
        query = query.where(Evaluation.course_id == course_id)
    return session.scalar(query.order_by((Evaluation.result_key == result_key).desc(), Evaluation.id.desc()).limit(1))


def episode_page(session: Session, *, evaluation_id: int, offset: int, limit: int) -> tuple[list[EpisodeResult], int]:
    """Episodes of an evaluation in order, from `offset`; and how many it has."""
    rows = session.scalars(select(EpisodeResult).where(EpisodeResult.evaluation_id == evaluation_id)
                           .order_by(EpisodeResult.index).offset(offset).limit(limit))
    total = session.scalar(select(func.count()).select_from(EpisodeResult)
                           .where(EpisodeResult.evaluation_id == evaluation_id))
    return list(rows), total or 0


def latest_evaluations(session: Session, *, submission_ids: list[int], result_keys: dict[int, str | None],
                       course_id: int | None = None) -> dict[int, Evaluation]:
    """Each submission's newest public evaluation of its key in `result_keys` (submission id -> key) if it
    has one, else its newest public one (of `course_id`'s assignments only, when given)."""
    if not submission_ids:
        return {}
    newest = select(func.max(Evaluation.id)).where(Evaluation.submission_id.in_(submission_ids),
                                                   Evaluation.track == PUBLIC_TRACKS)
    if course_id is not None:
        newest = newest.where(Evaluation.course_id == course_id)
    newest = newest.group_by(Evaluation.submission_id, Evaluation.result_key)
    shown: dict[int, Evaluation] = {}
    for evaluation in session.scalars(select(Evaluation).where(Evaluation.id.in_(newest)).order_by(Evaluation.id)):
        kept = shown.get(evaluation.submission_id)
        if kept is None or kept.result_key != result_keys.get(evaluation.submission_id):
            shown[evaluation.submission_id] = evaluation  # newer, and the kept one is not of the key
    return shown


def submissions_with_results(session: Session, *, result_key: str, course_id: int) -> set[int]:
    """Submissions with a public evaluation of `result_key` done, running or queued, in the course (each
    course's results are its own: a baseline evaluated in another course is not in this one)."""
    return set(session.scalars(select(Evaluation.submission_id).distinct().where(
        Evaluation.result_key == result_key, Evaluation.track == PUBLIC_TRACKS, Evaluation.course_id == course_id,
        Evaluation.status.in_((DONE, RUNNING, QUEUED)))))


def queued_evaluations(session: Session, *, assignment_id: int, other_than: str) -> list[Any]:
    """(evaluation id, submission id, job id) of the assignment's queued public evaluations whose key is
    not `other_than`: normal priority first, then the oldest."""
    return list(session.execute(
        select(Evaluation.id, Evaluation.submission_id, Job.id).join(Job, Job.evaluation_id == Evaluation.id)
        .where(Evaluation.assignment_id == assignment_id, Evaluation.track == PUBLIC_TRACKS,
               Evaluation.status == QUEUED, Job.status == QUEUED, Evaluation.result_key != other_than)
        .order_by(Job.priority, Evaluation.id)))


def retarget_evaluation(session: Session, *, evaluation_id: int, settings: dict[str, Any], result_key: str) -> bool:
    """Give a queued evaluation other settings; False if a worker took it meanwhile."""
    return bool(session.execute(update(Evaluation).where(Evaluation.id == evaluation_id, Evaluation.status == QUEUED)
                                .values(settings=settings, result_key=result_key)).rowcount)


def supersede_evaluation(session: Session, *, evaluation_id: int, job_id: int, reason: str) -> bool:
    """Fail a queued evaluation and its job for good, unrun; False if a worker took it meanwhile."""
    now = utcnow()
    if not session.execute(update(Job).where(Job.id == job_id, Job.status == QUEUED)
                           .values(status=FAILED, error=reason, finished_at=now)).rowcount:
        return False
    session.execute(update(Evaluation).where(Evaluation.id == evaluation_id)
                    .values(status=FAILED, error=reason, finished_at=now))
    return True


def submissions_of(session: Session, *, owner_ids: list[int]) -> list[Submission]:
    query = select(Submission).where(Submission.owner_id.in_(owner_ids)).order_by(Submission.id.desc())
    return list(session.scalars(query))


def course_submissions(session: Session, *, course_id: int | None, status: str | None = None,
                       assignment_id: int | None = None) -> list[Submission]:
    """Submissions of a course's users (of one assignment, if given) and of the baselines (they race
    in every course and are a reference on every board)."""
    owners = select(User.id).where((User.course_id == course_id) | (User.name == BASELINES_USER))
    query = select(Submission).where(Submission.owner_id.in_(owners))
    if assignment_id is not None:
        query = query.where((Submission.assignment_id == assignment_id) | (User.role == BASELINE)).join(
            User, Submission.owner_id == User.id)
    if status:
        query = query.where(Submission.status == status)
    return list(session.scalars(query.order_by(Submission.id)))


def ready_submissions(session: Session, *, owner_ids: list[int]) -> list[Submission]:
    query = select(Submission).where(Submission.owner_id.in_(owner_ids), Submission.status == READY)
    return list(session.scalars(query.order_by(Submission.id.desc())))


def ready_submission_of(session: Session, *, owner_id: int, submission_id: int) -> Submission | None:
    submission = session.get(Submission, submission_id)
    return submission if submission is not None and submission.owner_id == owner_id and \
        submission.status == READY else None


def latest_ready_submission(session: Session, *, owner_id: int) -> Submission | None:
    return session.scalar(select(Submission).where(Submission.owner_id == owner_id, Submission.status == READY)
                          .order_by(Submission.id.desc()).limit(1))


def ready_baseline_submissions(session: Session) -> list[Submission]:
    return list(session.scalars(select(Submission).join(User, Submission.owner_id == User.id).where(
        User.role == BASELINE, Submission.status == READY)))


def registered_baselines(session: Session, *, course_id: int) -> set[int]:
    """Ids of the baselines' submissions registered in the course (bootstrap: the first course)."""
    return set(session.scalars(select(Submission.id).join(User, Submission.owner_id == User.id)
                               .join(Assignment, Submission.assignment_id == Assignment.id)
                               .where(User.role == BASELINE, Assignment.course_id == course_id)))


def submissions_by_id(session: Session, *, ids: list[int]) -> dict[int, Submission]:
    if not ids:
        return {}
    return {s.id: s for s in session.scalars(select(Submission).where(Submission.id.in_(ids)))}


# --------------------------------------------------------------------------- status answers (Core)
# GET /api/submissions/{id} is what every student's page and `league submit --wait` poll: two Core
# statements, built once, read what the answer shows (league.server.api.routes.submissions.status_answer),
# instead of an ORM session's five queries and its objects.

_viewer, _owner, _chosen = User.__table__.alias("viewer"), User.__table__.alias("owner"), Submission.__table__.alias()
_submission, _assignment, _oldest = Submission.__table__, Assignment.__table__, Assignment.__table__.alias()
_evaluation = Evaluation.__table__
STATUS_SUBMISSION_COLUMNS = ("id", "name", "owner_id", "filename", "kind", "sha256", "size", "status", "error",
                             "obs_dim", "assignment_id", "late", "created_at", "updated_at", "public", "log")
STATUS_EVALUATION_COLUMNS = ("id", "status", "error", "settings", "result_key", "versions", "completed",
                             "episodes_total", "mean_return", "mean_steps", "mean_speed", "created_at",
                             "finished_at", "log")


def _status_statement():
    """The viewer (by token), the submission and its owner, the settings of the assignment whose results
    count for it, and whether it is the one its owner races (rounds.active_submission_ids) -- the same
    rules as the ORM's functions, in SQL: the viewer's course is theirs, else the first
    (api.deps.user_course); a baseline's results count by the viewer's course's default (oldest)
    assignment (results.submissions_current_keys); a student races their pick if it is a ready
    submission of theirs, else their latest ready one, a baseline every ready one."""
    viewer_course = func.coalesce(_viewer.c.course_id, select(func.min(Course.__table__.c.id)).scalar_subquery())
    default_assignment = select(func.min(_oldest.c.id)).where(_oldest.c.course_id == viewer_course).scalar_subquery()
    counted = case((_owner.c.role == BASELINE, default_assignment), else_=_submission.c.assignment_id)
    picked = select(_chosen.c.id).where(_chosen.c.id == _owner.c.active_submission_id,
                                        _chosen.c.owner_id == _owner.c.id, _chosen.c.status == READY)
    # the owner's submissions by their index (owner_id, created_at), not the ready ones of everyone by theirs
    latest = (select(func.max(case((_chosen.c.status == READY, _chosen.c.id))))
              .where(_chosen.c.owner_id == _owner.c.id))
    active = (_submission.c.status == READY) & (
        (_owner.c.role == BASELINE)
        | (_submission.c.id == func.coalesce(picked.scalar_subquery(), latest.scalar_subquery())))
    return (select(_viewer.c.id.label("viewer_id"), _viewer.c.role.label("viewer_role"),
                   _viewer.c.course_id.label("viewer_course_id"), _viewer.c.revoked_at.label("viewer_revoked_at"),
                   viewer_course.label("viewer_course"),
                   *(_submission.c[name] for name in STATUS_SUBMISSION_COLUMNS),
                   _owner.c.name.label("owner"), _owner.c.role.label("owner_role"),
                   _owner.c.course_id.label("owner_course_id"),
                   _assignment.c.id.label("counted_assignment_id"), _assignment.c.seed, _assignment.c.episodes,
                   _assignment.c.env_options, active.label("active"))
            .select_from(_viewer)
            .outerjoin(_submission, _submission.c.id == bindparam("submission_id"))
            .outerjoin(_owner, _owner.c.id == _submission.c.owner_id)
            .outerjoin(_assignment, _assignment.c.id == counted)
            .where(_viewer.c.token_hash == bindparam("token_hash")))


def _shown_evaluation_statement(by_course: bool, keyless: bool):
    """latest_evaluation's query, of the columns a status answer shows."""
    key = bindparam("result_key")
    query = select(*(_evaluation.c[name] for name in STATUS_EVALUATION_COLUMNS)).where(
        _evaluation.c.submission_id == bindparam("submission_id"), _evaluation.c.track == PUBLIC_TRACKS)
    if by_course:
        query = query.where(_evaluation.c.course_id == bindparam("course_id"))
    matches = _evaluation.c.result_key.is_(None) if keyless else _evaluation.c.result_key == key
    return query.order_by(matches.desc(), _evaluation.c.id.desc()).limit(1)


_STATUS = _status_statement()
_SHOWN_EVALUATION = {(by_course, keyless): _shown_evaluation_statement(by_course, keyless)
                     for by_course in (False, True) for keyless in (False, True)}


def status_row(connection: Connection, *, token: str, submission_id: int) -> Row | None:
    """What a status answer needs of the token's user and the submission (None: no user has the token;
    the submission's columns are None when there is no such submission)."""
    return connection.execute(_STATUS, {"token_hash": hash_token(token), "submission_id": submission_id}).first()


def shown_evaluation_row(connection: Connection, *, submission_id: int, result_key: str | None,
                         course_id: int | None = None) -> Row | None:
    """latest_evaluation, as a row of STATUS_EVALUATION_COLUMNS."""
    statement = _SHOWN_EVALUATION[course_id is not None, result_key is None]
    return connection.execute(statement, {"submission_id": submission_id, "result_key": result_key,
                                          "course_id": course_id}).first()


# --------------------------------------------------------------------------- people of a course


def active_students(session: Session, *, course_id: int | None) -> list[User]:
    return list(session.scalars(select(User).where(User.course_id == course_id, User.role == STUDENT,
                                                   User.revoked_at.is_(None)).order_by(User.id)))


def leaderboard_entries(session: Session, *, assignment: Assignment, result_key: str | None,
                        track: str = PUBLIC_TRACKS) -> list[Any]:
    """Every ready submission of the assignment's active students and of the baselines' account with a
    finished evaluation of `track` (private: of the finals' evaluations only), newest first, with its
    owner and the figures of its newest finished evaluation of `result_key`, else (`stale`) of its
    newest finished one: plain rows (one query,
    no objects: the board is recomputed after every evaluation of a deadline rush)."""
    # joined to a derived table of the newest ids, of the key and of any, from one pass over the
    # finished evaluations (not `id IN (subquery)`, which SQLite's planner ran 50x slower: 111 ms
    # against 2 ms for 600 evaluations)
    evaluations = (Evaluation.track == track) & (Evaluation.course_id == assignment.course_id)  # the course's own
    if track != PUBLIC_TRACKS:
        evaluations &= Evaluation.id.in_(select(StudentAssignment.final_evaluation_id).where(
            StudentAssignment.assignment_id == assignment.id))
    newest = (select(Evaluation.submission_id, func.max(Evaluation.id).label("any_id"),
                     func.max(case((Evaluation.result_key == result_key, Evaluation.id))).label("current_id"))
              .where(Evaluation.status == DONE, evaluations).group_by(Evaluation.submission_id).subquery())
    query = (select(Submission.id, Submission.name, Submission.public, Submission.owner_id,
                    User.name.label("owner"), User.role.label("owner_role"), Evaluation.completed,
                    Evaluation.episodes_total, Evaluation.mean_return, Evaluation.mean_steps, Evaluation.mean_speed,
                    newest.c.current_id.is_(None).label("stale"))
             .join(User, Submission.owner_id == User.id)
             .join(newest, newest.c.submission_id == Submission.id)
             .join(Evaluation, Evaluation.id == func.coalesce(newest.c.current_id, newest.c.any_id))
             .where(((User.course_id == assignment.course_id) & (User.role == STUDENT) & User.revoked_at.is_(None)
                     & (Submission.assignment_id == assignment.id)) | (User.role == BASELINE),
                    Submission.status == READY)
             .order_by(Submission.id.desc()))
    return list(session.execute(query))


def public_state_stamp(session: Session) -> tuple:
    """What the public answers (leaderboard, standings) are computed from changes with this, each
    part read from one index (or the few rows of courses): the newest finished evaluation and heat
    (their results are written as their job ends), revocations (the board's students) and the
    assignments' last change (their settings decide which results rank; a publication shows the
    private board). Uploads and
    validations change no public answer (a submission shows once an evaluation of it is done), nor
    does this stamp; a public flag or a roster change shows within the cache's maximum age."""
    def newest_finished(kind: str):
        return select(func.max(Job.finished_at)).where(Job.kind == kind).scalar_subquery()
    return tuple(session.execute(select(
        newest_finished(EVALUATE), newest_finished(RACE),
        select(func.max(User.revoked_at)).scalar_subquery(),
        select(func.count(User.revoked_at)).scalar_subquery(),
        select(func.max(Course.updated_at)).scalar_subquery(),
        select(func.max(Assignment.updated_at)).scalar_subquery())).one())


# --------------------------------------------------------------------------- races and championships


def races_started_since(session: Session, *, user: User, since: datetime) -> int:
    """Friendly races a user started in the window (the daily quota)."""
    return session.scalar(select(func.count(Race.id)).where(
        Race.created_by_id == user.id, Race.championship_id.is_(None), Race.created_at > since)) or 0


def races_page(session: Session, *, course_id: int, page: int, size: int, championship_id: int | None,
               entrant_ids: set[int] | None = None) -> tuple[list[Race], int]:
    """The course's races (with a car of `entrant_ids`, when given), newest first, and how many there are."""
    query = select(Race).where(Race.course_id == course_id)
    if championship_id is not None:
        query = query.where(Race.championship_id == championship_id)
    if entrant_ids is not None:  # entrants are JSON: picked here, from the course's races' few ids
        with_car = [race_id for race_id, entrants in session.execute(query.with_only_columns(Race.id, Race.entrants))
                    if any(entrant["submission_id"] in entrant_ids for entrant in entrants)]
        query = query.where(Race.id.in_(with_car))
    total = session.scalar(select(func.count()).select_from(query.subquery()))
    races = list(session.scalars(query.order_by(Race.id.desc()).offset((page - 1) * size).limit(size)))
    return races, total


def submission_ids_of(session: Session, *, owner_id: int) -> set[int]:
    return set(session.scalars(select(Submission.id).where(Submission.owner_id == owner_id)))


def course_championships(session: Session, *, course_id: int | None) -> list[Championship]:
    return list(session.scalars(select(Championship).where(Championship.course_id == course_id)
                                .order_by(Championship.id)))


def championship_round(session: Session, *, championship_id: int, number: int) -> ChampionshipRound | None:
    return session.scalar(select(ChampionshipRound).where(ChampionshipRound.championship_id == championship_id,
                                                          ChampionshipRound.number == number))


def course_jobs(session: Session, *, course_id: int | None, status: str | None, limit: int) -> list[Job]:
    """The course's latest jobs (_of_course), newest first."""
    query = select(Job).where(_of_course(course_id)).order_by(Job.id.desc()).limit(limit)
    if status:
        query = query.where(Job.status == status)
    return list(session.scalars(query))


def course_job(session: Session, *, course_id: int | None, job_id: int) -> Job | None:
    return session.scalar(select(Job).where(Job.id == job_id, _of_course(course_id)))


def _of_course(course_id: int | None):
    """Whether a job is the course's: its people's jobs, and the baselines' jobs made for it (their
    evaluations on its assignments; their validations and probes, in the course that registered them).
    Another course's evaluations of the baselines are that course's: never listed nor cancelled here."""
    people = select(User.id).where(User.course_id == course_id, User.role != BASELINE)
    baselines = select(User.id).where(User.role == BASELINE)
    evaluations = select(Evaluation.id).where(Evaluation.course_id == course_id)
    registered = select(Submission.id).join(Assignment, Submission.assignment_id == Assignment.id).where(
        Assignment.course_id == course_id)
    return Job.owner_id.in_(people) | (Job.owner_id.in_(baselines) & (
        Job.evaluation_id.in_(evaluations) | (Job.evaluation_id.is_(None) & Job.submission_id.in_(registered))))
