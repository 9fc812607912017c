"""Releases: the version's one home; `league migrate` refusing while processes of another version run,
and going down and up to a named revision (a rollback); `league backup` of every schema this
repository ever shipped."""
from __future__ import annotations

import importlib.metadata
import signal
import subprocess
import sys
import time
import tomllib
from datetime import timedelta

import pytest
from sqlalchemy import text

import league
from league.server.backup import backup
from league.server.core.clock import utcnow
from league.server.db.session import _scripts, head_revision, make_engine, revision_of, upgrade

from ..layout import REPO
from .backends import BACKENDS, fresh_backend
from .commands import server_command


def upgrade_to(engine, revision: str) -> None:
    with engine.connect() as connection:
        upgrade(connection, revision)


def test_the_version_has_one_home_the_package_metadata():
    """pyproject.toml's version is the installed metadata's (a checkout installed with -e is reinstalled
    after a bump: this fails until then), and every command names it."""
    declared = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert declared == importlib.metadata.version("microracer-league") == league.__version__
    for module in ("league", "league.server"):
        answer = subprocess.run([sys.executable, "-m", module, "--version"], capture_output=True, text=True,
                                timeout=60)
        assert (answer.returncode, answer.stdout.split()[-1]) == (0, declared), answer


def all_revisions() -> list[str]:
    """Every schema revision this repository shipped, the first first."""
    return [script.revision for script in reversed(list(_scripts().walk_revisions()))]


def beat_as(connection, version: str, seconds_ago: float, pid: int = 4321) -> None:
    """A row as a process of `version` writes it (the columns every schema since 0014 has)."""
    at = (utcnow() - timedelta(seconds=seconds_ago)).replace(tzinfo=None)
    connection.execute(text("INSERT INTO workers (host, pid, version, started_at, heartbeat_at) "
                            "VALUES ('old-box', :pid, :version, :at, :at)"), {"pid": pid, "version": version, "at": at})


def test_this_release_has_its_changelog_section_and_release_row_with_the_schema_it_needs():
    """The release procedure's facts (docs/RELEASING.md): the version being released has a CHANGELOG section
    naming the schema revision it needs, and a row in RELEASING.md's table with that revision."""
    import re

    version, schema = importlib.metadata.version("microracer-league"), head_revision()
    changelog = (REPO / "CHANGELOG.md").read_text()
    section = re.search(rf"^## \[{re.escape(version)}\].*?(?=^## )", changelog, re.M | re.S)
    assert section, f"CHANGELOG.md has no section ## [{version}]"
    assert f"**Schema revision {schema}**" in section[0] and "### Upgrade notes" in section[0]
    releases = (REPO / "docs" / "RELEASING.md").read_text()
    assert re.search(rf"^\| {re.escape(version)} \| {schema} \|", releases, re.M), "docs/RELEASING.md's table"


@pytest.mark.parametrize("kind", BACKENDS)
def test_migrate_refuses_while_processes_of_another_version_run_and_goes_down_and_up(kind, tmp_path):
    with fresh_backend(kind, tmp_path) as database_url:
        env = {"LEAGUE_DATABASE_URL": database_url, "LEAGUE_DATA_DIR": str(tmp_path / "data")}

        def migrate(*args: str) -> subprocess.CompletedProcess:
            return server_command(tmp_path, "migrate", *args, **env)

        assert server_command(tmp_path, "init", "--instructor", "prof", **env).returncode == 0
        engine = make_engine(database_url)
        with engine.begin() as connection:
            beat_as(connection, "0.1.0", seconds_ago=2)
            beat_as(connection, league.__version__, seconds_ago=1, pid=99)  # this version's: no obstacle

        refused = migrate("--to", "0017")
        assert refused.returncode == 2
        message = refused.stderr.splitlines()[-1]
        assert message.startswith(f"league: error: processes of another version than this one "
                                  f"({league.__version__}) use this database, and migrating under them would break "
                                  f"them: alive: worker 0.1.0 on old-box, pid 4321, last heartbeat "), message
        assert message.endswith("Stop them first (every API and worker of the old version; with Docker: "
                                "`docker compose stop`)."), message
        assert migrate("--to", "0017", "--force").returncode == 2  # --force forgets the dead only

        with engine.begin() as connection:  # it died (-9): silent, not yet expired
            connection.execute(text("UPDATE workers SET heartbeat_at = :at WHERE pid = 4321"),
                               {"at": (utcnow() - timedelta(seconds=45)).replace(tzinfo=None)})
        refused = migrate("--to", "0017")
        assert refused.returncode == 2 and "silent: worker 0.1.0 on old-box, pid 4321" in refused.stderr
        assert refused.stderr.rstrip().endswith("The silent ones have not beaten for over 30 s: if they are dead, "
                                                "run again with --force to forget them.")
        down = migrate("--to", "0017", "--force")  # the rollback's step: the schema the older release needs
        assert down.returncode == 0, down.stderr
        assert down.stderr.splitlines()[-1] == f"league: migrated from schema revision {head_revision()} to 0017"
        with engine.connect() as connection:
            assert revision_of(connection) == "0017"
            assert connection.scalar(text("SELECT name FROM users")) == "prof"  # the data stays
            assert connection.execute(text("SELECT pid, version FROM workers")).all() == [(99, league.__version__)]

        up = migrate()
        assert up.returncode == 0, up.stderr
        assert up.stderr.splitlines()[-1] == f"league: migrated from schema revision 0017 to {head_revision()}"
        unknown = migrate("--to", "0099")
        assert unknown.returncode == 2
        assert unknown.stderr.splitlines()[-1] == (f"league: error: no schema revision '0099' here: this "
                                                   f"installation knows {', '.join(all_revisions())}")
        engine.dispose()


def test_a_worker_of_a_release_before_processes_had_kinds_is_named_too(tmp_path):
    """Releases 0.1.0 (schemas 0014 to 0017) registered their workers only, in a table without `kind`."""
    with fresh_backend("sqlite", tmp_path) as database_url:
        engine = make_engine(database_url)
        upgrade_to(engine, "0017")
        with engine.begin() as connection:
            beat_as(connection, "0.1.0", seconds_ago=1)
        engine.dispose()
        refused = server_command(tmp_path, "migrate", LEAGUE_DATABASE_URL=database_url,
                                 LEAGUE_DATA_DIR=str(tmp_path / "data"))
    assert refused.returncode == 2 and "alive: worker 0.1.0 on old-box, pid 4321" in refused.stderr, refused.stderr


def test_backup_reads_every_schema_this_repository_shipped(tmp_path):
    """A league at each revision, from the first (no races yet), backs up as it is: `league backup`
    is the first step of an upgrade, so it must work on the oldest course."""
    database = tmp_path / "league.db"
    engine = make_engine(f"sqlite:///{database}")
    revisions = all_revisions()
    assert revisions[0] == "0001" and revisions[-1] == head_revision()
    for revision in revisions:
        upgrade_to(engine, revision)
        with engine.connect() as connection:
            assert revision_of(connection) == revision
        report = backup(engine, revision, tmp_path / f"at-{revision}.bak")
        assert report.revision == revision
        assert set(report.counts) == ({"users", "submissions", "evaluations", "jobs"} | (
            set() if revision == "0001" else {"races"}))
    engine.dispose()


@pytest.mark.parametrize("kind", BACKENDS)
def test_league_backup_of_the_first_schema(kind, tmp_path):
    """The command itself, on the first schema of each backend (PostgreSQL's is exported table by table
    into an SQLite file migrated to the same revision)."""
    with fresh_backend(kind, tmp_path) as database_url:
        engine = make_engine(database_url)
        upgrade_to(engine, "0001")
        with engine.begin() as connection:
            connection.execute(text("INSERT INTO courses (id, name, eval_seed, eval_episodes, eval_env_options, "
                                    "created_at, updated_at) VALUES (1, 'default', 0, 3, '{}', :now, :now)"),
                               {"now": utcnow().replace(tzinfo=None)})
        engine.dispose()
        done = server_command(tmp_path, "backup", str(tmp_path / "first.bak"), LEAGUE_DATABASE_URL=database_url,
                              LEAGUE_DATA_DIR=str(tmp_path / "data"))
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines()[-1].startswith(f"league: backed up to {tmp_path / 'first.bak'}: 0 users, "
                                                   f"0 submissions, 0 evaluations, 0 jobs (schema revision 0001, ")



def test_a_worker_whose_schema_is_migrated_under_it_stops_saying_what_to_do(tmp_path, caplog):
    """A running worker that finds, at a heartbeat, the database at a newer revision stops (as on SIGTERM:
    its running jobs are handed back) and `league worker` exits 3, with the reason logged."""
    from league.server.core.config import Settings
    from league.server.db.session import make_sessionmaker, migrate
    from league.server.jobs.queue import JobQueue
    from league.server.jobs.runner import WorkerContext
    from league.server.jobs.worker import Worker
    from league.server.storage import BlobStore

    with fresh_backend("sqlite", tmp_path) as database_url:
        settings = Settings(_env_file=None, data_dir=tmp_path / "data", database_url=database_url, bootstrap=False,
                            cpu_placement=False, worker_heartbeat_s=0.2)
        engine = make_engine(database_url)
        migrate(engine)
        context = WorkerContext(settings, make_sessionmaker(engine), JobQueue(engine), BlobStore(settings.data_dir),
                                handlers={})
        worker = Worker(context, threads=1, prepare_thread=lambda settings: None)
        worker.start()
        try:
            assert worker.outdated is None
            with engine.begin() as connection:
                connection.execute(text("UPDATE alembic_version SET version_num = '0099'"))
            deadline = time.monotonic() + 30
            while signal.SIGTERM not in worker.signals and time.monotonic() < deadline:
                time.sleep(0.05)
        finally:
            worker.stop()
            engine.dispose()
    assert worker.signals == [signal.SIGTERM]  # what run_forever acts on, as on a SIGTERM
    assert worker.outdated == (f"the database's schema changed under this running process (microracer-league "
                               f"{league.__version__}): this database is at revision 0099, written by a newer "
                               f"version of microracer-league (this one, {league.__version__}, knows revisions up to "
                               f"{head_revision()}): upgrade this installation, then restart it")
    assert f"worker stopping: {worker.outdated}" in caplog.messages
