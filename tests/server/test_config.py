"""Settings that cannot be wrong silently: misspelled variables warned about, every value's source and
the database said out loud (secrets masked), bad values and unreachable databases named, and the
settings table of the docs generated from `Settings`."""
from __future__ import annotations

import pytest
from pydantic import SecretStr

from league.server.core.config import (
    ConfigError, Settings, load_settings, setting_sources, settings_markdown, shown_value, unknown_variables,
)
from league.validation.limits import SandboxLimits

from .commands import REPO, server_command


def test_unknown_variables_are_named_with_the_closest_setting(tmp_path):
    env_file = tmp_path / ".env"
    env_file.write_text("LEAGUE_QUOTA_PER_DAYS=3\nLEAGUE_MAX_UPLOAD_MB=5\nOTHER=1\n")
    warnings = unknown_variables({"LEAGUE_DATABSE_URL": "postgresql://db-host/league", "LEAGUE_TOKEN": "lg_x",
                                  "LEAGUE_TEST_PG": "postgresql://", "LEAGUE_ZZZ": "1", "PATH": "/bin"}, env_file)
    assert warnings == [
        "LEAGUE_DATABSE_URL (in the environment) is not a setting and is ignored: did you mean LEAGUE_DATABASE_URL?",
        f"LEAGUE_QUOTA_PER_DAYS (in {env_file}) is not a setting and is ignored: did you mean LEAGUE_QUOTA_PER_DAY?",
        "LEAGUE_ZZZ (in the environment) is not a setting and is ignored (`league config` lists the settings)",
    ]


def test_the_removed_queue_settings_say_the_database_is_the_queue(tmp_path):
    """An upgraded deployment that still sets them learns that workers need the database only."""
    env_file = tmp_path / ".env"
    env_file.write_text("LEAGUE_QUEUE_NAME=league\n")
    assert unknown_variables({"LEAGUE_QUEUE_URL": "redis://redis:6379/0"}, env_file) == [
        f"LEAGUE_QUEUE_NAME (in {env_file}) is no longer a setting and is ignored: the database is the job queue "
        f"now: one queue per database",
        "LEAGUE_QUEUE_URL (in the environment) is no longer a setting and is ignored: the database is the job queue "
        "now: workers need only LEAGUE_DATABASE_URL (no Redis)",
    ]


def test_sources_say_where_each_value_came_from(tmp_path):
    env_file = tmp_path / ".env"
    env_file.write_text("LEAGUE_QUOTA_PER_DAY=7\nLEAGUE_MAX_UPLOAD_MB=5\n")
    sources = setting_sources({"data_dir": tmp_path, "worker_threads": None},
                              {"LEAGUE_MAX_UPLOAD_MB": "6", "league_job_nice": "5"}, env_file)
    assert (sources["data_dir"], sources["max_upload_mb"], sources["job_nice"], sources["quota_per_day"],
            sources["worker_threads"]) == ("command line", "environment", "environment", str(env_file), "default")


def test_a_value_that_cannot_be_read_names_its_variable(monkeypatch):
    monkeypatch.setenv("LEAGUE_MAX_UPLOAD_MB", "lots")
    with pytest.raises(ConfigError, match=r"^LEAGUE_MAX_UPLOAD_MB='lots': Input should be a valid number"):
        load_settings()


@pytest.mark.parametrize("name, value, said", [
    ("LEAGUE_QUOTA_PER_DAY", "-5", "LEAGUE_QUOTA_PER_DAY='-5': Input should be greater than or equal to 1 "
                                   "(range: [1, 10000])"),
    ("LEAGUE_MAX_UPLOAD_MB", "-1", "LEAGUE_MAX_UPLOAD_MB='-1': Input should be greater than 0 (range: (0, 1024])"),
    ("LEAGUE_LEASE_TIMEOUT_S", "0", "LEAGUE_LEASE_TIMEOUT_S='0': Input should be greater than 0 (range: (0, 86400])"),
    ("LEAGUE_WORKER_SILENT_AFTER_S", "1", "LEAGUE_WORKER_SILENT_AFTER_S=1.0 must be more than "
                                          "LEAGUE_WORKER_HEARTBEAT_S=5.0: a worker would be reported dead between "
                                          "two of its heartbeats"),
    ("LEAGUE_LEASE_TIMEOUT_S", "4", "LEAGUE_LEASE_TIMEOUT_S=4.0 must be more than LEAGUE_HEARTBEAT_INTERVAL_S=5.0: "
                                    "a running job's lease would run out between two renewals"),
    ("LEAGUE_TRACK_CACHE_SIZE", "5000", "LEAGUE_TRACK_CACHE_SIZE='5000': Input should be less than or equal to "
                                        "4096 (range: [0, 4096])"),
    ("LEAGUE_EVAL_ENV_OPTIONS", '{"obstacle": false}', "LEAGUE_EVAL_ENV_OPTIONS={'obstacle': False}: 'obstacle' is "
                                                       "not an option of the simulator: did you mean 'obstacles'?"),
    ("LEAGUE_EVAL_ENV_OPTIONS", '{"curves": 1000}', "LEAGUE_EVAL_ENV_OPTIONS={'curves': 1000}: curves must be an "
                                                    "integer in [5, 60], got 1000"),
    ("LEAGUE_EVAL_ENV_OPTIONS", '{"observation": "lidar"}', "LEAGUE_EVAL_ENV_OPTIONS={'observation': 'lidar'}: "
                                                            "observation is not an evaluation setting"),
])
def test_nonsense_values_are_refused_with_the_variable_the_value_and_the_range(monkeypatch, name, value, said):
    monkeypatch.setenv(name, value)
    with pytest.raises(ConfigError) as refused:
        load_settings()
    assert str(refused.value).startswith(said)


def test_every_numeric_setting_has_a_range():
    """A new number without bounds would take -5 or 0 silently: each has both ends (or a lower one and a
    reason to have no upper: none today)."""
    unbounded = [name for name, field in Settings.model_fields.items()
                 if field.annotation in (int, float, float | None)
                 and not any(getattr(m, side, None) is not None for m in field.metadata for side in ("le", "lt"))]
    assert unbounded == []


def test_init_refuses_an_unknown_env_option_and_stores_nothing(tmp_path):
    refused = server_command(tmp_path, "init", "--instructor", "prof", LEAGUE_EVAL_ENV_OPTIONS='{"obstacle": false}')
    assert refused.returncode != 0
    assert "LEAGUE_EVAL_ENV_OPTIONS" in refused.stderr and "did you mean 'obstacles'?" in refused.stderr
    assert not (tmp_path / "agents_submissions" / "league.db").exists()


def test_secrets_are_masked():
    assert shown_value("postgresql+psycopg://league:hunter2@db-host:5432/league") == \
        "postgresql+psycopg://league:***@db-host:5432/league"
    assert shown_value("redis://:hunter2@redis-host:6379/0") == "redis://:***@redis-host:6379/0"
    assert shown_value("sqlite:////srv/league/league.db") == "sqlite:////srv/league/league.db"
    assert shown_value(SecretStr("hunter2")) == "**********"


def test_league_config_prints_every_setting_its_source_and_the_database(tmp_path):
    (tmp_path / ".env").write_text("LEAGUE_QUOTA_PER_DAY=7\nLEAGUE_MAX_UPLOD_MB=5\n")
    shown = server_command(tmp_path, "config", "--data-dir", "semester",
                           LEAGUE_DATABASE_URL="postgresql+psycopg://league:hunter2@db-host:5432/league",
                           LEAGUE_DATABSE_URL="postgresql+psycopg://league:hunter2@db-host:5432/other")
    assert shown.returncode == 0, shown.stderr
    assert "hunter2" not in shown.stdout + shown.stderr
    lines = dict(map(str.strip, line.split("  # ")) for line in shown.stdout.splitlines())
    assert len(lines) == len(Settings.model_fields)
    assert lines["LEAGUE_DATABASE_URL=postgresql+psycopg://league:***@db-host:5432/league"] == "environment"
    assert lines["LEAGUE_QUOTA_PER_DAY=7"] == str(tmp_path / ".env")
    assert lines["LEAGUE_DATA_DIR=semester"] == f"command line: {tmp_path / 'semester'}"
    assert lines["LEAGUE_MAX_UPLOAD_MB=10.0"] == "default"
    assert shown.stderr.splitlines() == [
        "league: warning: LEAGUE_DATABSE_URL (in the environment) is not a setting and is ignored: did you mean "
        "LEAGUE_DATABASE_URL?",
        f"league: warning: LEAGUE_MAX_UPLOD_MB (in {tmp_path / '.env'}) is not a setting and is ignored: did you "
        f"mean LEAGUE_MAX_UPLOAD_MB?"]


def test_an_unreachable_database_is_named_with_its_setting_and_host(tmp_path):
    url = "postgresql+psycopg://league:hunter2@127.0.0.1:1/league"  # nothing listens on port 1
    for command in (("users", "list"), ("worker",), ("serve", "--no-worker")):
        failed = server_command(tmp_path, *command, LEAGUE_DATABASE_URL=url)
        assert failed.returncode == 2, failed.stderr
        assert "hunter2" not in failed.stderr
        last = failed.stderr.splitlines()[-1]
        assert last.startswith("league: error: LEAGUE_DATABASE_URL: cannot connect to "
                               "postgresql+psycopg://league:***@127.0.0.1:1/league: connection failed: "), last
        assert "Traceback" not in failed.stderr and "unexpected" not in failed.stderr


def test_the_sandbox_settings_default_to_the_toolkits_limits():
    """One home for the limits' defaults (league.validation.limits): the settings only show some of them in
    other units (ms, KB), and convert back exactly."""
    assert Settings.model_construct().sandbox_limits() == SandboxLimits()
    assert Settings.model_construct(step_deadline_ms=50, log_limit_kb=4).sandbox_limits() == \
        SandboxLimits(step_deadline_s=0.05, log_limit=4096)


def test_the_settings_table_of_the_docs_is_generated_from_settings():
    for name, field in Settings.model_fields.items():
        assert field.description, f"{name}: every setting says what it sets (docs/SETTINGS.md is made from it)"
    assert (REPO / "docs" / "SETTINGS.md").read_text() == settings_markdown(), \
        "docs/SETTINGS.md is stale: regenerate it with `league config --markdown > docs/SETTINGS.md`"


def test_the_database_password_comes_from_its_file_and_no_variable_holds_it(tmp_path, monkeypatch):
    secret = tmp_path / "db_password"
    secret.write_text("p@ss/word\n")
    monkeypatch.setenv("LEAGUE_DATABASE_URL", "postgresql+psycopg://league@db:5432/league")
    monkeypatch.setenv("LEAGUE_DATABASE_PASSWORD_FILE", str(secret))
    from sqlalchemy.engine import make_url

    url = make_url(load_settings().resolved_database_url)
    assert (url.username, url.password, url.host, url.database) == ("league", "p@ss/word", "db", "league")
    secret.write_text("\n")
    with pytest.raises(ConfigError, match=f"LEAGUE_DATABASE_PASSWORD_FILE={secret} is empty"):
        load_settings()
    monkeypatch.setenv("LEAGUE_DATABASE_PASSWORD_FILE", str(tmp_path / "missing"))
    with pytest.raises(ConfigError, match="cannot read it: No such file or directory"):
        load_settings()
