"""Request and response bodies of the API (they make the OpenAPI page at /docs)."""
from __future__ import annotations

from datetime import datetime, timezone
from typing import Annotated, Any, Literal

from pydantic import AwareDatetime, BaseModel, ConfigDict, Field, PlainSerializer, model_validator

from league.championship import DEFAULT_POINTS
from league.server.db.models import BOARD_VISIBILITIES

DbId = Annotated[int, Field(ge=1, le=2**63 - 1)]  # a row's id: a 64-bit integer
# a UTC time shown with its zone as "+00:00" (assignments' times); taken with any zone, never without one
UtcTime = Annotated[AwareDatetime, PlainSerializer(lambda t: t.astimezone(timezone.utc).isoformat(timespec="seconds"),
                                                   return_type=str, when_used="json")]


class UserOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    role: str
    course_id: int | None
    email: str | None
    student_id: str | None = Field(description="the school's id of the student (unique in the course), or null")
    canvas_id: str | None = Field(default=None, description="the Canvas user ID (from Canvas's gradebook export), "
                                                            "or null")
    sis_login_id: str | None = Field(default=None, description="the SIS Login ID (from Canvas's gradebook export), "
                                                               "or null")
    display_name: str | None = Field(description="what public boards show visitors instead of the name (unique in "
                                                 "the course); null: a \"Student N\" pseudonym")
    created_at: datetime
    active: bool


class QuotaOut(BaseModel):
    limit: int = Field(description="submissions per rolling 24 hours (rejected ones do not count)")
    used: int
    remaining: int
    next_free_at: datetime | None = Field(description="when a used slot frees up; null while some remain")


class UserMe(UserOut):
    upload_quota: QuotaOut | None = Field(description="students' uploads left; null for instructors (no quota)")


class UserUpdate(BaseModel):
    display_name: str | None = Field(max_length=200, description="shown on public boards to visitors instead of "
                                                                  "your name (names' rules, unique in the course); "
                                                                  "null or empty: a \"Student N\" pseudonym")


class PrivacySettings(BaseModel):
    board_visibility: Literal[BOARD_VISIBILITIES] = Field(
        description="who sees the course's boards (leaderboard, races and replays, championships and standings): "
                    "public (anyone; visitors see display names or pseudonyms, never names), members (its "
                    "logged-in students and instructors) or instructors (only; a student still sees their own races)")


class UserCreated(UserOut):
    token: str = Field(description="the API token: shown once, store it (Authorization: Bearer TOKEN)")


class RosterLine(BaseModel):
    line: int = Field(description="the line's number in the file (a header is line 1)")
    name: str | None = Field(description="the name the line gives, as far as it could be read")
    reason: str


class RosterFormat(BaseModel):
    delimiter: Literal["comma", "semicolon", "tab"]
    columns: dict[str, str] = Field(description="field (full, name, first, last, email, student_id, canvas_id, "
                                                "sis_login_id) -> the header's spelling; empty when the file has "
                                                "one name a line")
    layout: Literal["canvas", "plain"] = Field(description="canvas: Canvas's gradebook export (names \"Last, "
                                                           "First\", its ID, SIS User ID and SIS Login ID kept)")


class RosterCreated(BaseModel):
    format: RosterFormat = Field(description="how the file was read")
    created: list[UserCreated]
    skipped: list[RosterLine] = Field(description="students enrolled already (matched by student id or email when "
                                                  "the line gives them, else by name) or named twice in the file")
    errors: list[RosterLine] = Field(description="lines not created and why; the other lines were")


class UserCreate(BaseModel):
    name: str = Field(min_length=1, max_length=200)
    email: str | None = Field(default=None, max_length=300)
    student_id: str | None = Field(default=None, max_length=200)
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
    result_key: str = Field(description="results with the same key compare (settings and simulator version); "
                                        "`league evaluate --json` prints the key of a local run")
    versions: dict[str, Any] | None = Field(description="what produced it: {physics, track_format, package}; "
                                                        "null until done")
    stale: bool = Field(False, description="of other settings than the course's current ones: it does not rank")
    completed: int | None
    episodes_total: int | None
    mean_return: float | None
    mean_steps: float | None
    mean_speed: float | None
    created_at: datetime
    finished_at: datetime | None


class EvaluationSummary(EvaluationOut):
    log: str | None = Field(description="what the evaluation's sandbox printed (truncated)")


class EpisodePage(BaseModel):
    evaluation_id: int
    total: int = Field(description="episodes of the evaluation")
    items: list[EpisodeOut]


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
    assignment_id: int | None
    late: bool = Field(description="uploaded after its owner's due time, in the late window")
    created_at: datetime
    updated_at: datetime
    public: bool = Field(description="other students may race against it")
    active: bool = Field(False, description="it races in championship rounds (your pick, else your latest ready one)")
    evaluation: EvaluationOut | None = None


class SubmissionLinks(BaseModel):
    episodes: str | None = Field(description="the latest evaluation's episodes, paged (?offset=&limit=); "
                                             "null before an evaluation")


class SubmissionDetail(SubmissionOut):
    """The status answer pollers read: small (no episodes), with an ETag (If-None-Match: 304)."""

    log: str | None = Field(description="what the validation sandbox printed (truncated)")
    evaluation: EvaluationSummary | None = None
    links: SubmissionLinks


class EvaluationSettings(BaseModel):
    seed: int = Field(ge=0, lt=2**63, description="the tracks: the same seed gives everyone the same tracks")
    episodes: int = Field(ge=1, le=1000)
    env_options: dict[str, Any] = Field(default_factory=dict, description="options of league.MicroRacerEnv")


class EvaluationSettingsChange(EvaluationSettings):
    reevaluating: list[int] = Field(description="ids of the submissions queued to be evaluated with these settings "
                                                "(at low priority; none when results of them exist)")


class UploadLimits(BaseModel):
    """What an upload must fit (public: `league check` measures a model against it before uploading)."""

    max_upload_bytes: int
    quota_per_day: int
    sandbox_memory_mb: int
    step_deadline_ms: float = Field(description="CPU time of the model per observation of a call")
    first_call_allowance_ms: float = Field(description="banked extra CPU time for warm-up calls")
    run_cpu_s: float = Field(description="CPU time of the model over one evaluation or race")
    load_cpu_s: float = Field(description="CPU time to start the sandbox, load the model and dry-run it")


class RerunRequest(BaseModel):
    submission_id: DbId | None = Field(None, description="re-run this submission's evaluation")
    all: bool = Field(False, description="re-run every ready submission of the course (baselines included)")


class RerunOut(BaseModel):
    queued: list[int] = Field(description="ids of the submissions whose evaluation was queued")


class JobOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    kind: str
    submission_id: int | None
    evaluation_id: int | None
    race_id: int | None
    status: str
    priority: int = Field(description="0 normal, 1 low (re-evaluations: claimed when no normal job waits)")
    attempts: int
    worker_id: str | None
    error: str | None
    created_at: datetime
    started_at: datetime | None
    heartbeat_at: datetime | None
    finished_at: datetime | None


class SandboxIsolation(BaseModel):
    full: bool = Field(description="Landlock, seccomp and, for a root server, a user id of its own per sandbox: "
                                   "uploaded models run only then, unless not required")
    missing: list[str] = Field(description="what full isolation lacks here, each with what to do about it")
    required: bool
    network: str = Field(description="namespace, user-namespace or unavailable (seccomp refuses sockets anyway)")
    user: str = Field(description="own user id, root without capabilities, or the server's user")
    landlock: int = Field(description="the kernel's Landlock ABI version (0: none)")
    seccomp: bool
    runtime: str = Field(description="readable by the sandbox's user, or preloaded: loaded by its fork server "
                                     "before the change of user (a Python under a home only root may enter)")
    runtimes: list[str] = Field(description="those whose tiny model a probe sandbox loaded and ran, confined")
    problem: str | None = Field(description="why a probe sandbox failed, if one did")


class WorkerOut(BaseModel):
    host: str
    pid: int
    version: str
    started_at: datetime
    heartbeat_at: datetime = Field(description="its last heartbeat (every worker_heartbeat_s while it runs)")
    alive: bool = Field(description="heard from in the last worker_silent_after_s seconds")


class Health(BaseModel):
    status: Literal["ok", "degraded", "outdated"] = Field(
        description="degraded: no worker heard from in worker_silent_after_s (jobs would not run); outdated: the "
                    "database's schema is not this process's (an upgrade under it): both answer 503")
    reason: str | None = Field(description="why the status is not ok, and what to do (then the answer is a 503)")
    version: str = Field(description="the microracer-league version of this API process")
    schema_revision: str = Field(description="the database schema revision this version needs")
    database: str = Field(description="sqlite or postgresql: the database, which is also the job queue")
    queued_jobs: int
    oldest_queued_s: float | None = Field(description="how long the oldest queued job has waited (null: none waits)")
    worker_silent_after_s: float = Field(description="a worker silent this long is not counted alive")
    workers: list[WorkerOut] = Field(description="the registered workers, with their last heartbeat (a worker that "
                                                 "died without a word is listed until its row expires)")
    sandbox: SandboxIsolation = Field(description="how this machine's sandboxes are isolated")


class SubmissionUpdate(BaseModel):
    active: bool | None = Field(None, description="true: race this one in championships; false: back to the latest")
    public: bool | None = Field(None, description="let other students race against it")


# --------------------------------------------------------------------------- races and championships


class Page(BaseModel):
    total: int


class RaceCreate(BaseModel):
    submission_ids: list[DbId] = Field(min_length=2, max_length=100,
                                       description="one car each, in this order (car_0 first)")
    seed: int | None = Field(None, ge=0, lt=2**63, description="the track and start; default: drawn and stored")
    env_options: dict[str, Any] = Field(default_factory=dict, description="options of league.MicroRacerEnv")


class RaceCreated(BaseModel):
    id: int
    status: str


class Entrant(BaseModel):
    submission_id: int
    name: str
    owner: str


class ClassificationRow(Entrant):
    position: int
    car: str
    outcome: str = Field(description="finished, off_road, wrong_direction, too_slow, timeout or dnf")
    time: float = Field(description="seconds: the finish time, else when the car stopped")
    distance: float
    reason: str | None = Field(description="why the car stopped (for a DNF: what its agent did wrong)")


class RaceOut(BaseModel):
    id: int
    status: str = Field(description="pending, running, done or failed")
    error: str | None
    seed: int | None = Field(description="the track and start; null while the race is a heat of a round still "
                                         "being raced (a round's track is secret until then)")
    env_options: dict[str, Any]
    versions: dict[str, Any] | None = Field(description="what raced it: {physics, track_format, package}; "
                                                        "null until done")
    created_at: datetime
    finished_at: datetime | None
    championship_id: int | None
    round: int | None
    heat: int | None
    entrants: list[Entrant]
    classification: list[ClassificationRow] | None


class RacePage(Page):
    items: list[RaceOut]


class ChampionshipCreate(BaseModel):
    name: str = Field(min_length=1, max_length=100)
    env_options: dict[str, Any] = Field(default_factory=dict)
    heat_size: int = Field(10, ge=2, description="cars per heat; a larger field is split into balanced heats")
    points: list[int] = Field(default_factory=lambda: list(DEFAULT_POINTS), min_length=1,
                              max_length=100, description="points by finishing position in a heat")
    include_baselines: bool = True
    seed: int | None = Field(None, ge=0, lt=2**63, description="draws the rounds' heats (who races whom); "
                                                               "default: drawn. Tracks are drawn secretly per round")
    assignment: int | None = Field(None, ge=1, description="an assignment of your course (its id): the rounds race "
                                   "each student's final submission of it (their selection, else their best on "
                                   "its public board); default: none, each student's active submission")


class RoundOut(BaseModel):
    number: int
    status: str = Field(description="pending, running, done or failed")
    heats_done: int
    heats_total: int
    race_ids: list[int]
    track_seed: int | None = Field(description="the round's track, drawn secretly when the round is created; "
                                               "null until the round is over (done or failed)")
    heats: list[list[int]] = Field(description="submission ids of each heat")
    created_at: datetime


class ChampionshipOut(BaseModel):
    id: int
    name: str
    env_options: dict[str, Any]
    heat_size: int
    points: list[int]
    include_baselines: bool
    seed: int = Field(description="draws each round's heats; the tracks do not derive from it")
    assignment_id: int | None = Field(description="whose final submissions race; null: the students' active ones")
    created_at: datetime
    rounds: list[RoundOut]


class StandingRow(BaseModel):
    rank: int
    submission_id: int
    name: str
    owner: str
    points: int
    wins: int
    finishes: list[int] = Field(description="positions, one per heat raced")
    rating: float = Field(description="OpenSkill mu - 3 sigma")
    mu: float
    sigma: float


class StandingsPage(Page):
    items: list[StandingRow]


class LeaderboardRow(BaseModel):
    rank: int | None = Field(description="null for a stale row")
    stale: bool = Field(description="its results are all of other settings than the current ones: shown after "
                                    "the ranked rows, unranked, until it is evaluated again")
    owner: str
    submission_id: int
    name: str
    public: bool
    completed: int
    episodes: int
    mean_return: float
    mean_steps: float
    mean_speed: float
    rating: float | None = Field(description="course-wide OpenSkill mu - 3 sigma from championship heats")
    mu: float | None
    sigma: float | None


class LeaderboardPage(Page):
    items: list[LeaderboardRow]


class PackageFileOut(BaseModel):
    filename: str
    kind: str = Field(description="wheel: for machines like the server's (its Python and platform); sdist: any "
                                  "other (pip builds the simulator's core: a C compiler is needed)")
    sha256: str
    size: int
    url: str
    install: str = Field(description="the command that installs the toolkit from this file")


class PackageOut(BaseModel):
    """The league's own package, the code this server runs."""

    version: str
    python: str = Field(description="the server's Python (a wheel installs on this version only)")
    platform: str = Field(description="the server's platform (a wheel installs on this platform only)")
    files: list[PackageFileOut]


# --------------------------------------------------------------------------- assignments


class AssignmentTimes(BaseModel):
    opens_at: UtcTime | None = Field(None, description="uploads open (null: at once)")
    due_at: UtcTime | None = Field(None, description="uploads are on time before it (null: no deadline)")
    late_until: UtcTime | None = Field(None, description="late uploads are taken until then (after due_at)")
    late_penalty: float | None = Field(None, gt=0, le=1, description="a late final's score is multiplied by it")
    daily_quota: int | None = Field(None, ge=1, le=10_000, description="uploads per student per UTC day")
    auto_publish: bool = Field(False, description="publish the private board once every final is evaluated")

    @model_validator(mode="after")
    def _in_order(self):
        if self.opens_at and self.due_at and self.due_at <= self.opens_at:
            raise ValueError("due_at must be after opens_at")
        if self.late_until and (self.due_at is None or self.late_until <= self.due_at):
            raise ValueError("late_until needs a due_at before it")
        return self


class AssignmentCreate(AssignmentTimes):
    name: str = Field(min_length=1, max_length=100, pattern=r"^[^\s/][^/]*$")
    description: str = Field("", max_length=10_000)
    seed: int = Field(0, ge=0, lt=2**63, description="the public tracks (shown; the private ones are drawn)")
    episodes: int = Field(100, ge=1, le=10_000)
    env_options: dict[str, Any] = Field(default_factory=dict)


class AssignmentUpdate(BaseModel):
    """Only the fields sent change (times: null removes one)."""

    name: str | None = Field(None, min_length=1, max_length=100, pattern=r"^[^\s/][^/]*$")
    description: str | None = Field(None, max_length=10_000)
    seed: int | None = Field(None, ge=0, lt=2**63)
    episodes: int | None = Field(None, ge=1, le=10_000)
    env_options: dict[str, Any] | None = None
    opens_at: UtcTime | None = None
    due_at: UtcTime | None = None
    late_until: UtcTime | None = None
    late_penalty: float | None = Field(None, gt=0, le=1)
    daily_quota: int | None = Field(None, ge=1, le=10_000)
    auto_publish: bool | None = None
    keep_open: bool | None = Field(None, description="the automatic assignment only: it keeps taking uploads beside "
                                                     "the course's own assignments")


class FinalOut(BaseModel):
    submission_id: int | None = Field(description="the final submission: selected, else the best on the public board")
    selected: bool = Field(description="the student selected it (else: their best on the public board)")
    frozen_at: UtcTime | None = Field(description="when it was frozen (the student's close time); null before")
    decided: bool = Field(False, description="the final is decided: after the close time, once each upload made "
                                             "before it is validated and evaluated on the public tracks (until "
                                             "then, submission_id is what it would be now)")
    evaluation: EvaluationOut | None = Field(None, description="its private test: once published (instructors: "
                                                               "always)")


class AssignmentOut(BaseModel):
    id: int
    name: str
    description: str
    seed: int = Field(description="the public tracks: `league evaluate FILE --seed S --episodes N` reproduces them")
    episodes: int
    env_options: dict[str, Any]
    private_seed: int | None = Field(description="the private tracks: null until published (instructors: always)")
    opens_at: UtcTime | None
    due_at: UtcTime | None = Field(description="the assignment's due time (yours: my_due_at)")
    late_until: UtcTime | None
    late_penalty: float | None
    daily_quota: int | None
    auto_publish: bool
    published_at: UtcTime | None
    my_due_at: UtcTime | None = Field(None, description="your own due time (your extension, if any)")
    my_closes_at: UtcTime | None = Field(None, description="when you can no longer upload (late window included)")
    extended: bool = Field(False, description="your due time is an extension")
    state: str = Field("open", description="for you now: upcoming, open, late or closed")
    now: UtcTime = Field(description="the server's clock when answered (time left: my_due_at - now)")
    final: FinalOut | None = Field(None, description="yours (students)")
    rubric: dict[str, Any] | None = Field(None, description="how it is graded (league.server.course.grading); "
                                                            "null: not set")
    automatic: bool = Field(False, description="the course's automatic assignment (made with the course): closed to "
                                               "uploads once the course has assignments of its instructors, unless "
                                               "keep_open")
    keep_open: bool = Field(False, description="the automatic assignment keeps taking uploads beside the others")


class SelectionIn(BaseModel):
    submission_id: DbId | None = Field(description="a ready submission of yours in the assignment; null: your best")


class ExtensionIn(BaseModel):
    due_at: UtcTime


class ExtensionOut(BaseModel):
    assignment_id: int
    user_id: int
    due_at: UtcTime | None


class AssignmentBoard(LeaderboardPage):
    board: Literal["public", "private"]


class AuditEventOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    at: datetime
    actor_id: int | None = Field(description="the instructor's user id; null: an admin command (`league ...`)")
    actor_name: str
    action: str = Field(description="user.create, user.import, user.revoke, user.token, user.delete, job.cancel, "
                                    "evaluation.rerun, settings.evaluation, championship.create, round.run, "
                                    "round.retry, integrity.probe")
    target_kind: str = Field(description="user, job, submission, course, championship or roster")
    target_id: int | None
    details: dict[str, Any] = Field(description="ids and figures of the action (never a token; never a deleted "
                                                "student's name)")


class AuditPage(Page):
    items: list[AuditEventOut]


class IntegritySubmission(BaseModel):
    id: int
    name: str
    owner: str
    baseline: bool = Field(description="a submission of the `baselines` account")
    kind: str = Field(description="onnx or torchscript")
    sha256: str
    created_at: datetime


class IntegrityGroup(BaseModel):
    kind: Literal["identical_file", "same_behaviour", "baseline_copy"] = Field(
        description="identical_file: one file (sha256) uploaded by several students; same_behaviour: actions on a "
                    "probe set (public, or the assignment's secret one) that follow each other up to a "
                    "per-dimension affine map (rescaled, offset or clipped copies, re-exports) within the "
                    "tolerance; baseline_copy: a bundled baseline's file or behaviour")
    students: list[str]
    baseline: str | None = Field(description="the baseline copied (baseline_copy)")
    distance: float | None = Field(description="the largest behaviour distance between two of its submissions, "
                                               "each pair on the probe set where it is closest (0: the "
                                               "same actions up to an affine map; null: fewer than two "
                                               "probed)")
    submissions: list[IntegritySubmission]


class UncomparedSubmission(IntegritySubmission):
    reason: str = Field(description="not yet probed on a set it is compared on (POST /api/integrity/probe), "
                                    "or the model failed on one: compared by file and the sets it has")


class IntegrityReport(BaseModel):
    tolerance: float = Field(description="submissions whose behaviour distance (0: the same actions up "
                                             "to a per-dimension affine map; 1: unrelated) is within this "
                                             "are the same behaviour")
    probes: int = Field(description="observations in the public probe set (2 actions each; an "
                                        "assignment's secret set has 192)")
    submissions: int = Field(description="ready submissions the report covers (the course's and the baselines')")
    compared: int = Field(description="of them, those whose actions on every probe set they are "
                                               "compared on are known")
    groups: list[IntegrityGroup]
    not_compared: list[UncomparedSubmission]


class ProbesQueued(BaseModel):
    queued: list[int] = Field(description="ids of the submissions queued to be probed (low priority)")


class CanvasMatchOut(BaseModel):
    students: int = Field(description="the students of the Canvas grade file")
    by_id: list[str] = Field(description="students whose line carries an id Canvas matches: its ID, SIS User ID, "
                                         "or a SIS Login ID from Canvas's export")
    by_email: list[str] = Field(description="students with only an email as SIS Login ID: matched only where the "
                                            "institution's Canvas logins are email addresses")
    by_name: list[str] = Field(description="students with no id: matched only by the exact name")
    summary: str = Field(description="the counts in words, as the console and `league grades --check` say them")


class GradeRowOut(BaseModel):
    name: str = Field(description="the student's name, or the baseline agent's")
    status: Literal["graded", "no final", "open", "pending", "stale", "reference"] = Field(
        description="graded; no final (0 points); open (final not frozen yet), pending (the final not decided "
                    "yet: an upload still to be validated or evaluated on the public tracks; or its private "
                    "evaluation not done, or failed), stale (its private result is of other settings): empty "
                    "points; reference: a baseline (no rank, no grade)")
    role: Literal["student", "baseline"]
    email: str | None
    student_id: str | None
    submission_id: int | None = Field(description="the final submission")
    completed: float | None = Field(description="the fraction of the private episodes completed (0-1)")
    mean_return: float | None
    mean_speed: float | None
    rank: int | None = Field(description="among students only (equal figures share a rank)")
    students: int | None = Field(description="how many students were ranked with this one")
    late: bool
    penalty: float | None = Field(description="the factor the points were multiplied by (the late penalty, else 1)")
    points: float | None
    revoked: bool
    revised: bool = Field(description="its private result changed after the assignment was published")
    note: str | None = Field(description="how it changed (re-evaluated, or graded after the publication)")


class GradesOut(BaseModel):
    assignment_id: int
    assignment: str
    published: bool
    max_points: float
    late_penalty: float | None
    rubric: dict[str, Any]
    rows: list[GradeRowOut] = Field(description="graded best first, baselines among them, then the rest by name")


class MyGradeOut(GradeRowOut):
    assignment_id: int
    assignment: str
    max_points: float
