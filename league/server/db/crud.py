"""Database functions (keyword-only arguments). They add and flush; callers commit."""
from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from league.server.db.models import (
    EVALUATE, FAILED, QUEUED, REJECTED, VALIDATE, Blob, Course, Evaluation, Job, Submission, User,
    utcnow,
)
from league.server.security import hash_token, new_token

DEFAULT_COURSE = "default"
BASELINES_USER = "baselines"
QUOTA_WINDOW = timedelta(hours=24)
NAME_PATTERN = re.compile(r"^[\w.@+-][\w .@+-]{0,99}$")
NOT_COUNTED = (REJECTED, FAILED)  # a student's quota is not eaten by uploads the league refused or lost


class InvalidName(ValueError):
    """An invalid or taken user name (message shown to the caller)."""


# --------------------------------------------------------------------------- courses


def get_or_create_course(session: Session, *, name: str, evaluation: dict[str, Any]) -> Course:
    course = session.scalar(select(Course).where(Course.name == name))
    if course is None:
        course = Course(name=name, eval_seed=evaluation["seed"], eval_episodes=evaluation["episodes"],
                        eval_env_options=dict(evaluation["env_options"]))
        session.add(course)
        session.flush()
    return course


def first_course(session: Session) -> Course | None:
    return session.scalar(select(Course).order_by(Course.id).limit(1))


def set_evaluation_settings(session: Session, *, course: Course, seed: int, episodes: int,
                            env_options: dict[str, Any]) -> Course:
    course.eval_seed, course.eval_episodes, course.eval_env_options = seed, episodes, dict(env_options)
    session.flush()
    return course


# --------------------------------------------------------------------------- users


def check_user_name(session: Session, *, name: str) -> str:
    name = name.strip()
    if not NAME_PATTERN.match(name):
        raise InvalidName(f"invalid user name {name!r}: 1-100 letters, digits, spaces or . @ + - _")
    if session.scalar(select(User.id).where(User.name == name)) is not None:
        raise InvalidName(f"user name {name!r} is already taken")
    return name


def create_user(session: Session, *, name: str, role: str, course: Course | None,
                created_by: User | None = None, with_token: bool = True) -> tuple[User, str | None]:
    """Add a user; return it with its token (shown once, stored hashed)."""
    name = check_user_name(session, name=name)
    token = new_token() if with_token else None
    user = User(name=name, role=role, course_id=course.id if course else None,
                token_hash=hash_token(token) if token else None, created_by_id=created_by.id if created_by else None)
    session.add(user)
    session.flush()
    return user, token


def user_by_token(session: Session, *, token: str) -> User | None:
    return session.scalar(select(User).where(User.token_hash == hash_token(token)))


def user_by_name(session: Session, *, name: str) -> User | None:
    return session.scalar(select(User).where(User.name == name))


def course_users(session: Session, *, course_id: int | None) -> list[User]:
    return list(session.scalars(select(User).where(User.course_id == course_id).order_by(User.id)))


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
    """Keep a file's bytes once (callers commit; an IntegrityError means another upload stored them)."""
    if session.get(Blob, sha256) is None:
        session.add(Blob(sha256=sha256, size=len(data), data=data))
        session.flush()


def blob_data(session: Session, *, sha256: str) -> bytes | None:
    blob = session.get(Blob, sha256)
    return None if blob is None else blob.data



def create_submission(session: Session, *, owner: User, name: str, filename: str, kind: str, sha256: str,
                      size: int, max_attempts: int) -> tuple[Submission, Job]:
    """A new submission and its validation job (both queued in this transaction)."""
    submission = Submission(owner_id=owner.id, name=name, filename=filename, kind=kind, sha256=sha256, size=size)
    session.add(submission)
    session.flush()
    job = create_job(session, kind=VALIDATE, submission_id=submission.id, max_attempts=max_attempts)
    return submission, job


def create_job(session: Session, *, kind: str, submission_id: int | None = None, evaluation_id: int | None = None,
               race_id: int | None = None, payload: dict[str, Any] | None = None, max_attempts: int = 3) -> Job:
    job = Job(kind=kind, submission_id=submission_id, evaluation_id=evaluation_id, race_id=race_id,
              payload=payload or {}, status=QUEUED, max_attempts=max_attempts)
    session.add(job)
    session.flush()
    return job


def create_evaluation(session: Session, *, submission: Submission, course: Course | None,
                      settings: dict[str, Any], max_attempts: int) -> tuple[Evaluation, Job]:
    evaluation = Evaluation(submission_id=submission.id, course_id=course.id if course else None,
                            settings=settings, status=QUEUED)
    session.add(evaluation)
    session.flush()
    job = create_job(session, kind=EVALUATE, submission_id=submission.id, evaluation_id=evaluation.id,
                     max_attempts=max_attempts)
    return evaluation, job


def latest_evaluation(session: Session, *, submission_id: int) -> Evaluation | None:
    return session.scalar(select(Evaluation).where(Evaluation.submission_id == submission_id)
                          .order_by(Evaluation.id.desc()).limit(1))


def latest_evaluations(session: Session, *, submission_ids: list[int],
                       status: str | None = None) -> dict[int, Evaluation]:
    """Each submission's newest evaluation, or its newest one in `status`."""
    if not submission_ids:
        return {}
    newest = select(func.max(Evaluation.id)).where(Evaluation.submission_id.in_(submission_ids))
    if status:
        newest = newest.where(Evaluation.status == status)
    newest = newest.group_by(Evaluation.submission_id)
    rows = session.scalars(select(Evaluation).where(Evaluation.id.in_(newest)))
    return {evaluation.submission_id: evaluation for evaluation in rows}


def submissions_of(session: Session, *, owner_ids: list[int]) -> list[Submission]:
    query = select(Submission).where(Submission.owner_id.in_(owner_ids)).order_by(Submission.id.desc())
    return list(session.scalars(query))


def course_submissions(session: Session, *, course_id: int | None, status: str | None = None) -> list[Submission]:
    """Submissions of a course's users and of the baselines (they race in every course)."""
    owners = select(User.id).where((User.course_id == course_id) | (User.name == BASELINES_USER))
    query = select(Submission).where(Submission.owner_id.in_(owners))
    if status:
        query = query.where(Submission.status == status)
    return list(session.scalars(query.order_by(Submission.id)))
