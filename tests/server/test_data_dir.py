"""One data directory, said out loud: every command names its database, only `league init` and `league
serve` create one, only they and `league migrate` change its schema (under a lock), and a process
whose code does not match the schema says what to do."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
from sqlalchemy import create_engine, text

import league
from league.server.db.session import head_revision, upgrade

from .backends import fresh_backend
from .commands import REPO, server_command


def revision(url: str) -> str | None:
    engine = create_engine(url)
    try:
        with engine.connect() as connection:
            return connection.execute(text("SELECT version_num FROM alembic_version")).scalar_one_or_none()
    finally:
        engine.dispose()


def test_commands_run_from_the_wrong_directory_create_nothing_and_say_where_they_looked(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    looked_at = home / "agents_submissions" / "league.db"
    for command in (("users", "add", "carol"), ("backup", "league.bak"), ("worker",)):
        failed = server_command(home, *command)
        assert failed.returncode == 2, failed.stderr
        named, error = failed.stderr.splitlines()[-2:]  # (the worker logs its line with a timestamp)
        assert named.endswith(f"database sqlite:///{looked_at} (the default data directory: agents_submissions in "
                              f"the current directory)"), named
        assert error == (f"league: error: no league database at {looked_at}: run this command where the server runs, "
                         f"or point it at the server's data directory with --data-dir DIR or LEAGUE_DATA_DIR=DIR "
                         f"(LEAGUE_DATABASE_URL for PostgreSQL); `league init` creates a new league there")
        assert failed.stdout == ""  # no token printed
        assert list(home.iterdir()) == []  # nothing created

    created = server_command(tmp_path, "init", "--instructor", "prof", "--data-dir", "course")
    assert created.returncode == 0, created.stderr
    assert created.stdout.startswith("lg_")
    assert created.stderr.splitlines()[:2] == [
        f"league: database sqlite:///{tmp_path / 'course' / 'league.db'} (the data directory given by --data-dir)",
        f"league: created a new league (schema revision {head_revision()})"]
    listed = server_command(home, "users", "list", LEAGUE_DATA_DIR=str(tmp_path / "course"))
    assert listed.returncode == 0, listed.stderr
    assert listed.stderr == (f"league: database sqlite:///{tmp_path / 'course' / 'league.db'} (the data directory "
                             f"LEAGUE_DATA_DIR, from the environment)\n")
    assert listed.stdout.split() == ["1", "prof", "instructor", "active", "default"]  # its course last
    again = server_command(tmp_path, "init", "--data-dir", "course")
    assert again.returncode == 0 and "already holds a league" in again.stderr


@pytest.mark.parametrize("kind", ["sqlite", "postgres"])
def test_two_processes_starting_together_migrate_once(kind, tmp_path):
    with fresh_backend(kind, tmp_path) as url:
        env = {"LEAGUE_DATABASE_URL": url, "LEAGUE_DATA_DIR": str(tmp_path / "data")}
        clean = {name: value for name, value in os.environ.items() if not name.upper().startswith("LEAGUE_")}
        starts = [subprocess.Popen([sys.executable, "-m", "league.server", "init", "--instructor", name],
                                   cwd=tmp_path, env={**clean, "PYTHONPATH": str(REPO), **env}, text=True,
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE) for name in ("ann", "bob")]
        outputs = [start.communicate(timeout=120) for start in starts]
        assert [start.returncode for start in starts] == [0, 0], outputs
        assert revision(url) == head_revision()
        listed = server_command(tmp_path, "users", "list", **env)
        assert sorted(line.split()[1] for line in listed.stdout.splitlines()) == ["ann", "bob"]


def test_a_schema_older_or_newer_than_the_code_is_refused_with_what_to_do(tmp_path):
    url = f"sqlite:///{tmp_path / 'league.db'}"
    engine = create_engine(url)
    with engine.connect() as connection:
        upgrade(connection, "0005")  # a database of an older release
    env = {"LEAGUE_DATABASE_URL": url}
    for command in (("users", "list"), ("worker",), ("init",)):  # (a backup of it is allowed: taken before migrating)
        refused = server_command(tmp_path, *command, **env)
        assert refused.returncode == 2, refused.stderr
        assert refused.stderr.splitlines()[-1] == (
            f"league: error: this database is at revision 0005, older than this installation's {head_revision()}: "
            f"run `league migrate` (back it up first: `league backup FILE`)"), command
    assert revision(url) == "0005"  # nobody migrated it
    migrated = server_command(tmp_path, "migrate", **env)
    assert migrated.returncode == 0, migrated.stderr
    assert migrated.stderr.splitlines()[-1] == f"league: migrated from schema revision 0005 to {head_revision()}"

    with engine.begin() as connection:  # as a newer release leaves it
        connection.execute(text("UPDATE alembic_version SET version_num = '0999'"))
    engine.dispose()
    for command in (("users", "list"), ("worker",), ("migrate",), ("serve", "--no-worker")):
        refused = server_command(tmp_path, *command, **env)
        assert refused.returncode == 2, refused.stderr
        assert refused.stderr.splitlines()[-1] == (
            f"league: error: this database is at revision 0999, written by a newer version of microracer-league "
            f"(this one, {league.__version__}, knows revisions up to {head_revision()}): upgrade this "
            f"installation"), command
