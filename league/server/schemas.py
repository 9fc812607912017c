"""Request and response bodies of the API (they make the OpenAPI page at /docs)."""
from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field


class Message(BaseModel):
    detail: str


class UserOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    role: str
    course_id: int | None
    created_at: datetime
    active: bool


class UserCreated(UserOut):
    token: str = Field(description="the API token: shown once, store it (Authorization: Bearer TOKEN)")


class UserCreate(BaseModel):
    name: str = Field(min_length=1, max_length=100)
    role: Literal["student"] = "student"


class EpisodeOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    index: int
    seed: int
    steps: int
    episode_return: float = Field(serialization_alias="return")
    mean_speed: float
    outcome: str
    reason: str | None


class EvaluationOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    status: str = Field(description="queued, running, done or failed")
    error: str | None
    settings: dict[str, Any]
    completed: int | None
    episodes_total: int | None
    mean_return: float | None
    mean_steps: float | None
    mean_speed: float | None
    created_at: datetime
    finished_at: datetime | None


class EvaluationDetail(EvaluationOut):
    log: str | None
    episodes: list[EpisodeOut]


class SubmissionCreated(BaseModel):
    id: int
    status: str


class SubmissionOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    owner_id: int
    owner: str
    filename: str
    kind: str
    sha256: str
    size: int
    status: str = Field(description="pending, validating, ready, rejected or failed")
    error: str | None = Field(description="why the submission was rejected or failed")
    obs_dim: int | None
    created_at: datetime
    updated_at: datetime
    evaluation: EvaluationOut | None = None


class SubmissionDetail(SubmissionOut):
    log: str | None = Field(description="what the validation sandbox printed (truncated)")
    evaluation: EvaluationDetail | None = None


class EvaluationSettings(BaseModel):
    seed: int = Field(ge=0, lt=2**63, description="the tracks: the same seed gives everyone the same tracks")
    episodes: int = Field(ge=1, le=1000)
    env_options: dict[str, Any] = Field(default_factory=dict, description="options of league.MicroRacerEnv")


class RerunRequest(BaseModel):
    submission_id: int | None = Field(None, description="re-run this submission's evaluation")
    all: bool = Field(False, description="re-run every ready submission of the course (baselines included)")


class RerunOut(BaseModel):
    queued: list[int] = Field(description="ids of the submissions whose evaluation was queued")


class JobOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    kind: str
    submission_id: int | None
    evaluation_id: int | None
    status: str
    attempts: int
    worker_id: str | None
    error: str | None
    created_at: datetime
    started_at: datetime | None
    heartbeat_at: datetime | None
    finished_at: datetime | None


class Health(BaseModel):
    status: str
    database: str
    queue: str
    queued_jobs: int
