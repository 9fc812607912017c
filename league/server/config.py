"""The league server's settings: one pydantic-settings class, read from LEAGUE_* variables and `.env`.

Every default runs the embedded league (SQLite database and SQLite task queue in the data
directory); point `database_url` at PostgreSQL and `queue_url` at Redis to run workers on
several machines.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from league.validation.limits import MAX_UPLOAD_MB, SandboxLimits

MB = 1024 * 1024
LIMITS = SandboxLimits()  # the league's defaults (the toolkit's: `league check` uses them without a server)
BUNDLED_BASELINES = Path(__file__).resolve().parents[1] / "baselines" / "agents"  # package data: travels with it


class Settings(BaseSettings):
    """Environment variables are the field names in upper case with the prefix LEAGUE_,
    e.g. LEAGUE_DATABASE_URL; dicts are JSON (LEAGUE_EVAL_ENV_OPTIONS='{"obstacles": false}')."""

    model_config = SettingsConfigDict(env_prefix="LEAGUE_", env_file=".env", extra="ignore")

    # where things live
    data_dir: Path = Field(Path("agents_submissions"), description="submission store, SQLite files")
    database_url: str | None = Field(None, description="SQLAlchemy URL; default sqlite:///DATA_DIR/league.db")
    queue_url: str | None = Field(None, description="redis://host:port/db, or default SQLite DATA_DIR/queue.db")
    queue_name: str = Field("league", description="Huey queue name (the Redis key prefix)")
    baselines_dir: Path | None = Field(None, description="agents registered under the `baselines` account on an "
                                                         "empty database; default: the ones bundled with the "
                                                         "package (league/baselines/agents); an empty "
                                                         "directory: the heuristic driver")
    bootstrap: bool = Field(True, description="register and evaluate the baselines on an empty database")

    # uploads and quotas
    max_upload_mb: float = Field(MAX_UPLOAD_MB, description="largest model file accepted")
    request_body_timeout_s: float = Field(30.0, gt=0, description="a request body that stops arriving this long, or "
                                                                  "past it arrives slower than 8 KB/s, is refused "
                                                                  "(408): slow clients cannot hold the API")

    # connections (league serve; league/server/api/connections.py)
    max_connections: int = Field(1000, ge=1, description="connections the API holds at once; one more closes the "
                                                         "one waiting longest for a request, else is refused (503); "
                                                         "kept within the open-file limit, which serve raises")
    max_connections_per_client: int = Field(200, ge=0, description="connections from one address (IPv6: one /64) "
                                                                  "at once; more are refused (503). 0: no bound "
                                                                  "(behind a reverse proxy, every client is the proxy)")
    request_head_timeout_s: float = Field(10.0, gt=0, description="a connection that has not sent a whole request "
                                                                  "line and headers this long after it opened or "
                                                                  "after its last answer is closed")
    quota_per_day: int = Field(10, description="submissions per student per rolling 24 h (rejected ones are free)")
    max_jobs_in_flight: int = Field(3, ge=1, description="a student's uploads and races waiting or running at once; "
                                                         "more are refused until one is done")

    # races and championships
    max_race_cars: int = Field(10, description="cars in one race or championship heat")
    race_quota_per_day: int = Field(20, description="friendly races a student may start per rolling 24 h")
    public_cache_s: float = Field(2.0, ge=0, description="seconds the leaderboard and standings are served from "
                                                         "memory while the database's state stamp is unchanged "
                                                         "(a finished evaluation or heat is shown at once)")
    public_cache_max_age_s: float = Field(5.0, ge=0, description="the oldest leaderboard or standings answer ever "
                                                                 "served: past public_cache_s one is served while "
                                                                 "its successor is computed, up to this age")

    # sandbox limits
    sandbox_memory_mb: int = Field(LIMITS.memory_mb, description="address space a model may use on top of its "
                                                                 "runtime")
    race_memory_mb: int = Field(2048, ge=64, description="what the cars of one race may use together, on top of "
                                                          "their runtimes (each gets its share, at most "
                                                          "sandbox_memory_mb)")
    sandbox_cpu_seconds: int = Field(LIMITS.cpu_seconds, description="CPU time of one sandbox process")
    step_deadline_ms: float = Field(LIMITS.step_deadline_s * 1000, description="CPU time of the model per "
                                                                              "observation of a call")
    first_call_allowance_ms: float = Field(LIMITS.first_call_allowance_s * 1000,
                                           description="banked extra CPU time for warm-up calls")
    run_cpu_s: float = Field(LIMITS.run_cpu_s, description="CPU time of the model over one evaluation or race")
    load_cpu_s: float = Field(LIMITS.load_cpu_s, description="CPU time to start the sandbox, load the model and "
                                                             "dry-run it")
    sandbox_uid_base: int = Field(LIMITS.uid_base, ge=0, lt=2**31 - 2**22,
                                  description="a root worker runs each sandbox as user id sandbox_uid_base + its pid "
                                              "(no account needed); 0: as root without capabilities")
    sandbox_require_isolation: bool = Field(LIMITS.require_isolation, description="run no uploaded model unless sandboxes get Landlock "
                                                              "and seccomp (the start-up log and /api/health say "
                                                              "what they get)")
    sandbox_max_restarts: int = Field(LIMITS.max_restarts, description="sandbox crashes tolerated in one "
                                                                       "evaluation")
    log_limit_kb: int = Field(LIMITS.log_limit // 1024, description="sandbox output kept per run")

    # evaluation defaults (of a new course; instructors change them through the API)
    eval_seed: int = 0
    eval_episodes: int = 100
    eval_env_options: dict[str, Any] = Field(default_factory=dict)

    # jobs: leases as in fishtest, a job whose worker stops heart-beating is given to another
    worker_threads: int = Field(1, description="jobs one worker process runs at once")
    worker_cpus: str = Field("", description="CPUs a `league worker` and its sandboxes run on, as taskset "
                                             "lists them ('1', '0-3,6'); empty: all (a race then uses more "
                                             "than one CPU)")
    cpu_placement: bool = Field(True, description="place job threads and their sandboxes on CPUs: an "
                                                   "evaluation on one CPU, the job threads of a machine on "
                                                   "CPUs of their own (see league/server/jobs/placement.py)")
    cpu_slots_dir: str = Field(str(Path(tempfile.gettempdir()) / "league-cpu-slots"),
                               description="directory the workers of one machine share to split its CPUs; "
                                           "empty: each worker splits only its own CPUs between its threads")
    job_nice: int = Field(10, ge=0, le=19, description="CPU priority (nice) of job threads and their sandboxes: "
                                                       "the API stays responsive while they race")
    heartbeat_interval_s: float = 5.0
    lease_timeout_s: float = Field(60.0, description="a running job without heartbeat for this long is re-queued")
    reaper_interval_s: float = 10.0
    requeue_queued_after_s: float = Field(600.0, description="re-send a job left queued this long (lost message)")
    max_job_attempts: int = 3

    def sandbox_limits(self) -> SandboxLimits:
        """What each sandbox may use, in the toolkit's units."""
        return SandboxLimits(memory_mb=self.sandbox_memory_mb, cpu_seconds=self.sandbox_cpu_seconds,
                             step_deadline_s=self.step_deadline_ms / 1000,
                             first_call_allowance_s=self.first_call_allowance_ms / 1000,
                             run_cpu_s=self.run_cpu_s, load_cpu_s=self.load_cpu_s,
                             uid_base=self.sandbox_uid_base, require_isolation=self.sandbox_require_isolation,
                             max_restarts=self.sandbox_max_restarts, log_limit=self.log_limit_kb * 1024)

    @property
    def max_upload_bytes(self) -> int:
        return int(self.max_upload_mb * MB)

    @property
    def resolved_database_url(self) -> str:
        return self.database_url or f"sqlite:///{self.data_dir.resolve() / 'league.db'}"

    @property
    def resolved_queue_url(self) -> str:
        return self.queue_url or f"sqlite:///{self.data_dir.resolve() / 'queue.db'}"

    @property
    def resolved_baselines_dir(self) -> Path:
        return self.baselines_dir or BUNDLED_BASELINES

    def default_evaluation(self) -> dict[str, Any]:
        return {"seed": self.eval_seed, "episodes": self.eval_episodes, "env_options": dict(self.eval_env_options)}
