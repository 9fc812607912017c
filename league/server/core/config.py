"""The league server's settings: one pydantic-settings class, read from LEAGUE_* variables and `.env`.

Every default runs the embedded league (an SQLite database in the data directory); point
`database_url` at PostgreSQL to run workers on several machines (the database is the job queue).
docs/SETTINGS.md is generated from this class (`league config --markdown`).

A setting cannot be wrong silently: `load_settings` names the variable of a value it cannot
read, `unknown_variables` the LEAGUE_* names that are no setting (with the closest one), and
`setting_sources` where each value came from (`league config` prints them, secrets masked).
"""
from __future__ import annotations

import difflib
import json
import os
import tempfile
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any, Literal
from urllib.parse import urlsplit

from dotenv import dotenv_values
from pydantic import Field, PrivateAttr, SecretStr, ValidationError, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

import league
from league.constants import TRACK_CACHE_SIZE
from league.validation.limits import MAX_UPLOAD_MB, SandboxLimits

MB = 1024 * 1024
LIMITS = SandboxLimits()  # the league's defaults (the toolkit's: `league check` uses them without a server)
BUNDLED_BASELINES = Path(league.__file__).resolve().parent / "baselines" / "agents"  # package data: travels with it
ENV_PREFIX, ENV_FILE = "LEAGUE_", ".env"
# LEAGUE_* variables that other parts of the package read (not server settings)
OTHER_VARIABLES = {
    "LEAGUE_SERVER": "the league server the student commands (`league submit`, ...) talk to",
    "LEAGUE_TOKEN": "the API token of those commands",
    "LEAGUE_DEBUG": "any value: a failing `league` command prints its traceback",
}
OWN_PREFIXES = ("LEAGUE_TEST_", "LEAGUE_BENCH_")  # the test suite's and the benchmarks' own variables
# settings of earlier versions, and why they are gone (warned about when still set)
REMOVED_VARIABLES = {
    "LEAGUE_QUEUE_URL": "the database is the job queue now: workers need only LEAGUE_DATABASE_URL (no Redis)",
    "LEAGUE_QUEUE_NAME": "the database is the job queue now: one queue per database",
    "LEAGUE_REQUEUE_QUEUED_AFTER_S": "workers claim queued jobs straight from the database: nothing is re-sent",
}


# (shorter, longer, why): the second setting must be larger than the first
CROSS_RULES = (
    ("worker_heartbeat_s", "worker_silent_after_s", "a worker would be reported dead between two of its heartbeats"),
    ("heartbeat_interval_s", "lease_timeout_s", "a running job's lease would run out between two renewals"),
)


class ConfigError(Exception):
    """A setting that cannot be used as given (its variable named)."""


class Settings(BaseSettings):
    """Environment variables are the field names in upper case with the prefix LEAGUE_,
    e.g. LEAGUE_DATABASE_URL; dicts are JSON (LEAGUE_EVAL_ENV_OPTIONS='{"obstacles": false}')."""

    model_config = SettingsConfigDict(env_prefix=ENV_PREFIX, env_file=ENV_FILE, extra="ignore")
    _database_password: str | None = PrivateAttr(None)  # read from database_password_file

    # where things live
    data_dir: Path = Field(Path("agents_submissions"), description="the server's folder, relative to the current "
                                                                   "directory: the SQLite database (league.db) and "
                                                                   "local copies of model files")
    database_url: str | None = Field(None, description="the database, as an SQLAlchemy URL "
                                                       "(postgresql+psycopg://user:password@host/league); "
                                                       "default: sqlite:///DATA_DIR/league.db")
    database_password_file: Path | None = Field(None, description="a file holding the database's password, put "
                                                                  "into database_url (a Docker secret: the "
                                                                  "password then appears in no environment)")
    baselines_dir: Path | None = Field(None, description="agents registered under the `baselines` account on an "
                                                         "empty database; default: the ones bundled with the "
                                                         "package (league/baselines/agents); an empty "
                                                         "directory: the heuristic driver")
    bootstrap: bool = Field(True, description="register and evaluate the baselines on an empty database")

    # uploads and quotas
    max_upload_mb: float = Field(MAX_UPLOAD_MB, gt=0, le=1024, description="largest model file accepted")
    request_body_timeout_s: float = Field(30.0, gt=0, le=3600,
                                          description="a request body that stops arriving this long, or "
                                                      "past twice this arrives slower than 8 KB/s, is "
                                                      "refused (408): slow clients cannot hold the API")

    # connections (league serve; league/server/api/connections.py)
    max_connections: int = Field(1000, ge=1, le=1_000_000,
                                 description="connections the API holds at once; one more closes the "
                                             "one waiting longest for a request, else is refused (503); "
                                             "kept within the open-file limit, which serve raises")
    max_connections_per_client: int = Field(200, ge=0, le=1_000_000,
                                            description="connections from one address (IPv6: one /64) "
                                                        "at once; more are refused (503). 0: no bound "
                                                        "(behind a reverse proxy, every client is the proxy)")
    request_head_timeout_s: float = Field(10.0, gt=0, le=3600,
                                          description="a connection that has not sent a whole request "
                                                      "line and headers this long after it opened or "
                                                      "after its last answer is closed")
    quota_per_day: int = Field(10, ge=1, le=10_000,
                               description="submissions per student per rolling 24 h (rejected ones are free)")
    max_jobs_in_flight: int = Field(3, ge=1, le=1000,
                                    description="a student's uploads and races waiting or running at once; "
                                                "more are refused until one is done")

    # races and championships
    max_race_cars: int = Field(10, ge=2, le=100, description="cars in one race or championship heat")
    race_quota_per_day: int = Field(20, ge=0, le=10_000,
                                    description="friendly races a student may start per rolling 24 h")
    public_cache_s: float = Field(2.0, ge=0, le=3600,
                                  description="seconds the leaderboard and standings are served from "
                                              "memory while the database's state stamp is unchanged "
                                              "(a finished evaluation or heat is shown at once)")
    public_cache_max_age_s: float = Field(5.0, ge=0, le=3600,
                                          description="the oldest leaderboard or standings answer ever "
                                                      "served: past public_cache_s one is served while "
                                                      "its successor is computed, up to this age")
    board_visibility: Literal["public", "members", "instructors"] = Field(
        "members", description="who sees a new course's boards (leaderboard, races, standings): public (anyone; "
                               "visitors who are not logged in see display names, never real names), members "
                               "(its logged-in students and instructors) or instructors; instructors change it "
                               "with PUT /api/settings/privacy or on the console")

    # integrity report (league/server/course/integrity.py)
    integrity_tolerance: float = Field(0.1, gt=0, le=1, description="two submissions behave alike when their "
                                                                    "behaviour distance on a probe set is within "
                                                                    "this (league/server/course/integrity.py; copies "
                                                                    "rescaled, clipped or re-exported: below 0.05, "
                                                                    "distinct agents here: 0.3 to 1)")

    # sandbox limits
    sandbox_memory_mb: int = Field(LIMITS.memory_mb, ge=64, le=1024 * 1024,
                                   description="address space a model may use on top of its "
                                               "runtime")
    race_memory_mb: int = Field(2048, ge=64, le=1024 * 1024,
                                description="what the cars of one race may use together, on top of "
                                            "their runtimes (each gets its share, at most "
                                            "sandbox_memory_mb)")
    sandbox_cpu_seconds: int = Field(LIMITS.cpu_seconds, ge=1, le=86_400, description="CPU time of one sandbox process")
    step_deadline_ms: float = Field(LIMITS.step_deadline_s * 1000, gt=0, le=60_000,
                                    description="CPU time of the model per "
                                                "observation of a call")
    first_call_allowance_ms: float = Field(LIMITS.first_call_allowance_s * 1000, ge=0, le=600_000,
                                           description="banked extra CPU time for warm-up calls")
    run_cpu_s: float = Field(LIMITS.run_cpu_s, gt=0, le=86_400,
                             description="CPU time of the model over one evaluation or race")
    load_cpu_s: float = Field(LIMITS.load_cpu_s, gt=0, le=3600,
                              description="CPU time to start the sandbox, load the model and "
                                          "dry-run it")
    sandbox_uid_base: int = Field(LIMITS.uid_base, ge=0, lt=2**31 - 2**22,
                                  description="a root worker runs each sandbox as user id sandbox_uid_base + its pid "
                                              "(no account needed); 0: as root without capabilities")
    sandbox_require_isolation: bool = Field(LIMITS.require_isolation,
                                            description="run no uploaded model unless sandboxes get Landlock "
                                                        "and seccomp (the start-up log and /api/health say "
                                                        "what they get)")
    sandbox_max_restarts: int = Field(LIMITS.max_restarts, ge=0, le=100, description="sandbox crashes tolerated in one "
                                                                       "evaluation")
    log_limit_kb: int = Field(LIMITS.log_limit // 1024, ge=1, le=100 * 1024, description="sandbox output kept per run")

    # evaluation defaults (of a new course; instructors change them through the API)
    eval_seed: int = Field(0, ge=0, lt=2**63, description="seed of a new course's evaluation tracks")
    eval_episodes: int = Field(100, ge=1, le=1000, description="episodes of a new course's evaluations")
    eval_env_options: dict[str, Any] = Field(default_factory=dict, description="environment options of a new "
                                                                               "course's evaluations, as JSON")

    # jobs: leases as in fishtest, a job whose worker stops heart-beating is given to another
    worker_threads: int = Field(1, ge=1, le=256, description="jobs one worker process runs at once")
    worker_cpus: str = Field("", description="CPUs a `league worker` and its sandboxes run on, as taskset "
                                             "lists them ('1', '0-3,6'); empty: all (a race then uses more "
                                             "than one CPU)")
    cpu_placement: bool = Field(True, description="place job threads and their sandboxes on CPUs: an "
                                                   "evaluation on one CPU, the job threads of a machine on "
                                                   "CPUs of their own (see league/server/jobs/placement.py)")
    cpu_slots_dir: str = Field(str(Path(tempfile.gettempdir()) / "league-cpu-slots"),
                               description="directory the workers of one machine share to split its CPUs; "
                                           "empty: each worker splits only its own CPUs between its threads",
                               json_schema_extra={"shown_default": "$TMPDIR/league-cpu-slots"})
    track_cache_size: int = Field(TRACK_CACHE_SIZE, ge=0, le=4096,
                                  description="episode starts (track and map, ~1.7 MB each) a worker keeps for "
                                              "the next evaluations on the same seeds: every submission of "
                                              "an assignment is evaluated on the same tracks; hold its "
                                              "public and private episodes, of every open assignment")
    job_nice: int = Field(10, ge=0, le=19, description="CPU priority (nice) of job threads and their sandboxes: "
                                                       "the API stays responsive while they race")
    heartbeat_interval_s: float = Field(5.0, gt=0, le=3600,
                                        description="how often a running job's worker renews its lease")
    lease_timeout_s: float = Field(60.0, gt=0, le=86_400,
                                   description="a running job without heartbeat for this long is re-queued")
    reaper_interval_s: float = Field(10.0, gt=0, le=3600,
                                     description="how often each worker looks for jobs whose worker stopped")
    queue_poll_s: float | None = Field(None, gt=0, le=600,
                                       description="how often an idle worker looks for queued jobs in the "
                                                   "database; default 0.5 on SQLite, 2 on PostgreSQL "
                                                   "(an enqueue also wakes workers at once: LISTEN/NOTIFY "
                                                   "on PostgreSQL, the commit's change to the database's "
                                                   "files on SQLite)")
    worker_heartbeat_s: float = Field(5.0, gt=0, le=3600,
                                      description="how often a worker or API process says it is alive "
                                                  "(the workers table; /api/health, league migrate)")
    worker_silent_after_s: float = Field(30.0, gt=0, le=86_400,
                                         description="a worker not heard from this long is not counted "
                                                     "alive: /api/health answers 503 (degraded) while no "
                                                     "worker is; a process silent twice as long is "
                                                     "forgotten")
    max_job_attempts: int = Field(3, ge=1, le=100, description="a job whose worker dies this many times fails for good")

    # monitoring (league/server/metrics.py, core/logs.py)
    metrics_token: SecretStr | None = Field(None, description="a bearer token that reads /metrics (Prometheus' "
                                                              "`authorization` credentials) and nothing else; "
                                                              "instructors' tokens read it too")
    log_format: Literal["text", "json"] = Field("text", description="log lines of the API, uvicorn and the workers: "
                                                                   "text (timestamp level logger: message) or json "
                                                                   "(one object a line)")
    log_level: Literal["debug", "info", "warning", "error"] = Field("info", description="the least severe log "
                                                                                        "lines written")
    log_file: Path | None = Field(None, description="write the log lines to this file instead of stderr, rotated "
                                                    "at log_file_max_mb (league serve's worker writes NAME-worker"
                                                    ".EXT beside it: one writer per file)")
    log_file_max_mb: float = Field(100.0, gt=0, le=100_000, description="a log file this large is renamed to "
                                                                        "NAME.1 (NAME.1 to NAME.2, ...) and a "
                                                                        "new one started")
    log_file_backups: int = Field(5, ge=0, le=1000, description="rotated log files kept (the oldest is deleted)")

    @field_validator("eval_env_options")
    @classmethod
    def _simulator_options(cls, options: dict[str, Any]) -> dict[str, Any]:
        """The names and values the simulator takes (a typo such as "obstacle" would be stored in every
        new course and refused by each of its evaluations)."""
        from league.options import RaceOptions  # the simulator's options, checked as an env checks them

        if "observation" in options:
            raise ValueError("observation is not an evaluation setting: it follows each agent's input size")
        known = [field.name for field in fields(RaceOptions) if field.name != "observation"]
        for name in options:
            if name not in known:
                closest = difflib.get_close_matches(name, known, n=1)
                hint = f"did you mean {closest[0]!r}? " if closest else ""
                raise ValueError(f"{name!r} is not an option of the simulator: {hint}the options are "
                                 f"{', '.join(known)}")
        try:
            RaceOptions(**options)
        except (TypeError, ValueError) as error:
            raise ValueError(str(error)) from None
        return options

    @model_validator(mode="after")
    def _read_password_file(self) -> Settings:
        if self.database_password_file is None:
            return self
        if not self.database_url:
            raise ValueError("LEAGUE_DATABASE_PASSWORD_FILE needs LEAGUE_DATABASE_URL (the database without its "
                             "password: postgresql+psycopg://league@db-host/league)")
        try:
            password = self.database_password_file.read_text(encoding="utf-8").strip()
        except OSError as error:
            raise ValueError(f"LEAGUE_DATABASE_PASSWORD_FILE={self.database_password_file}: cannot read it: "
                             f"{error.strerror}") from None
        if not password:
            raise ValueError(f"LEAGUE_DATABASE_PASSWORD_FILE={self.database_password_file} is empty")
        self._database_password = password
        return self

    @model_validator(mode="after")
    def _consistent(self) -> Settings:
        """Rules between settings: each pair named with its values and what must hold."""
        for shorter, longer, why in CROSS_RULES:
            if getattr(self, longer) <= getattr(self, shorter):
                raise ValueError(f"{variable(longer)}={getattr(self, longer)} must be more than "
                                 f"{variable(shorter)}={getattr(self, shorter)}: {why}")
        return self

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
        if self._database_password is not None:
            from sqlalchemy.engine import make_url

            return make_url(self.database_url).set(password=self._database_password) \
                .render_as_string(hide_password=False)
        return self.database_url or f"sqlite:///{self.data_dir.resolve() / 'league.db'}"

    @property
    def resolved_queue_poll_s(self) -> float:
        if self.queue_poll_s is not None:
            return self.queue_poll_s
        return 0.5 if self.resolved_database_url.startswith("sqlite") else 2.0

    @property
    def resolved_baselines_dir(self) -> Path:
        return self.baselines_dir or BUNDLED_BASELINES

    def default_evaluation(self) -> dict[str, Any]:
        return {"seed": self.eval_seed, "episodes": self.eval_episodes, "env_options": dict(self.eval_env_options)}


def variable(field: str) -> str:
    return ENV_PREFIX + field.upper()


def load_settings(**overrides: Any) -> Settings:
    """Settings from the environment, `.env` and `overrides` (command-line options, None: not given);
    a value that cannot be read raises ConfigError naming its variable."""
    given = {name: value for name, value in overrides.items() if value is not None}
    try:
        return Settings(**given)
    except ValidationError as error:
        problems = [problem(item) for item in error.errors()]
        raise ConfigError("; ".join(problems)) from None


def problem(item: Mapping[str, Any]) -> str:
    """One refused value: its variable, the value and why ("LEAGUE_QUOTA_PER_DAY='-5': Input should be
    greater than or equal to 1 (range: [1, 10000])"); a rule between settings names its own."""
    message = item["msg"].removeprefix("Value error, ")
    if not item["loc"]:
        return message
    name = str(item["loc"][0])
    return f"{variable(name)}={item.get('input')!r}: {message}{allowed_range(name)}"


def allowed_range(name: str) -> str:
    """" (range: 1 to 10000)" for a bounded numeric setting, else ""."""
    field = Settings.model_fields.get(name)
    if field is None:
        return ""
    low = high = None
    for bound in field.metadata:
        for attribute, side in (("ge", "["), ("gt", "("), ("le", "]"), ("lt", ")")):
            value = getattr(bound, attribute, None)
            if value is not None:
                if attribute in ("ge", "gt"):
                    low = f"{side}{value}"
                else:
                    high = f"{value}{side}"
    if low is None and high is None:
        return ""
    return f" (range: {low or '(-inf'}, {high or 'inf)'})"  # [a, b] includes its ends, (a, b) does not


def env_file_values(path: Path = Path(ENV_FILE)) -> dict[str, str]:
    """The LEAGUE_* lines of a `.env` file (upper-cased names, as pydantic-settings matches them)."""
    if not path.is_file():
        return {}
    return {name.upper(): value or "" for name, value in dotenv_values(path).items()
            if name.upper().startswith(ENV_PREFIX)}


def unknown_variables(environ: Mapping[str, str] = os.environ, env_file: Path = Path(ENV_FILE)) -> list[str]:
    """A warning for each LEAGUE_* variable (environment or `.env`) that nothing reads: a misspelled
    setting would otherwise be ignored and its default used."""
    known = {variable(name) for name in Settings.model_fields} | set(OTHER_VARIABLES)
    found = {name.upper(): "the environment" for name in environ if name.upper().startswith(ENV_PREFIX)}
    found.update({name: str(env_file.resolve()) for name in env_file_values(env_file) if name not in found})
    warnings = []
    for name, where in sorted(found.items()):
        if name in known or name.startswith(OWN_PREFIXES):
            continue
        if name in REMOVED_VARIABLES:
            warnings.append(f"{name} (in {where}) is no longer a setting and is ignored: {REMOVED_VARIABLES[name]}")
            continue
        closest = difflib.get_close_matches(name.removeprefix(ENV_PREFIX), [k.removeprefix(ENV_PREFIX) for k in known],
                                            n=1, cutoff=0.7)  # the shared prefix would make every name close
        hint = f": did you mean {ENV_PREFIX}{closest[0]}?" if closest else " (`league config` lists the settings)"
        warnings.append(f"{name} (in {where}) is not a setting and is ignored{hint}")
    return warnings


def setting_sources(overrides: Mapping[str, Any] = {}, environ: Mapping[str, str] = os.environ,
                    env_file: Path = Path(ENV_FILE)) -> dict[str, str]:
    """Where each setting's value comes from: a command-line option, the environment, `.env`, or
    its default (the order in which they win)."""
    in_environment = {name.upper() for name in environ}
    in_file = env_file_values(env_file)
    sources = {}
    for name in Settings.model_fields:
        if overrides.get(name) is not None:
            sources[name] = "command line"
        elif variable(name) in in_environment:
            sources[name] = "environment"
        elif variable(name) in in_file:
            sources[name] = str(env_file.resolve())
        else:
            sources[name] = "default"
    return sources


def database_origin(settings: Settings, sources: Mapping[str, str]) -> str:
    """Which setting names the database and where its value came from (said with the database's URL)."""
    if settings.database_url:
        return f"LEAGUE_DATABASE_URL, from {_place(sources['database_url'])}"
    source = sources["data_dir"]
    if source == "default":
        return f"the default data directory: {settings.data_dir} in the current directory"
    if source == "command line":
        return "the data directory given by --data-dir"
    return f"the data directory LEAGUE_DATA_DIR, from {_place(source)}"


def database_setting(settings: Settings, sources: Mapping[str, str]) -> str:
    """The option or variable to change to name another database."""
    if settings.database_url:
        return "LEAGUE_DATABASE_URL"
    return "--data-dir" if sources["data_dir"] == "command line" else "LEAGUE_DATA_DIR"


def _place(source: str) -> str:
    return "the environment" if source == "environment" else source


def mask_url(text: str) -> str:
    """A URL with its password replaced by ***: 'postgresql://league:***@db-host/league'."""
    parts = urlsplit(text)
    if "://" not in text or parts.password is None:
        return text
    userinfo, _, host = parts.netloc.rpartition("@")
    return parts._replace(netloc=f"{userinfo.partition(':')[0]}:***@{host}").geturl()


def shown_value(value: Any) -> str:
    """A setting's value as its variable would be written, secrets masked."""
    if isinstance(value, SecretStr):
        return "**********" if value.get_secret_value() else ""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (dict, list)):
        return json.dumps(value)
    return mask_url(str(value))


def describe_settings(settings: Settings, sources: Mapping[str, str]) -> str:
    """`league config`: every setting as a line of `.env`, and where its value came from."""
    lines = [(f"{variable(name)}={shown_value(getattr(settings, name))}", _source_note(settings, name, sources[name]))
             for name in Settings.model_fields]
    width = max(len(line) for line, _ in lines)
    return "\n".join(f"{line:<{width}}  # {source}" for line, source in lines)


def _source_note(settings: Settings, name: str, source: str) -> str:
    """The source, and what a relative path or an unset value stands for ("default: sqlite:///...")."""
    value, resolved = getattr(settings, name), getattr(settings, f"resolved_{name}", None)
    if value is None and resolved is not None:
        return f"{source}: {shown_value(resolved)}"
    if isinstance(value, Path) and not value.is_absolute():
        return f"{source}: {value.resolve()}"
    return source


def settings_markdown() -> str:
    """docs/SETTINGS.md: every setting in one table (`league config --markdown` prints it)."""
    rows = ["| Variable | Default | Range | What it sets |", "|---|---|---|---|"]
    for name, field in Settings.model_fields.items():
        extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
        default = extra.get("shown_default", shown_value(field.get_default(call_default_factory=True)))
        bounds = allowed_range(name).removeprefix(" (range: ").removesuffix(")")
        rows.append(f"| `{variable(name)}` | {f'`{default}`' if default != '' else ''} | {bounds} | "
                    f"{field.description} |")
    others = ["| Variable | What it sets |", "|---|---|"]
    others += [f"| `{name}` | {what} |" for name, what in OTHER_VARIABLES.items()]
    return "\n".join([
        "# Settings", "",
        "<!-- Generated by `league config --markdown > docs/SETTINGS.md` from league/server/core/config.py; "
        "tests/server/test_config.py checks that it matches. -->", "",
        "The league server reads every setting from an environment variable, or from a line of a `.env` "
        "file in the directory it starts in (the environment wins). `league config` prints the values in "
        "effect and where each came from; a `LEAGUE_*` variable that is no setting is warned about at "
        "start, with the closest name. Dicts are JSON: `LEAGUE_EVAL_ENV_OPTIONS='{\"obstacles\": false}'`.",
        "", "A value outside its range (`[a, b]` includes its ends, `(a, b)` does not) is refused when a "
        "command starts, naming the variable, the value and the range; so is a pair that breaks one of these "
        "rules:", "", *[f"- `{variable(longer)}` more than `{variable(shorter)}`: else {why}."
                      for shorter, longer, why in CROSS_RULES],
        "- `LEAGUE_EVAL_ENV_OPTIONS`: the simulator's option names and values (`league.RaceOptions`), "
        "without `observation`.",
        "", *rows, "",
        "Other parts of the package read these:", "", *others, "",
    ])
