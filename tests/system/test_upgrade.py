"""Upgrades keep everything: a league written by an earlier release (that release's own code, from `git
archive` of its commit, run as a server with its own PYTHONPATH) and upgraded with this code (`league
migrate`) answers every read as it did, field by field over the fields both versions have.

It needs the repository's history (CI clones main whole); the releases' compiled core is built once per
version of its sources (copied from this checkout's while they did not change), and kept between runs
in CORE_CACHE under the hash of those sources, this Python and this Cython (about 20 s of CPU a build,
two builds a run: the build is not what this file tests).
"""
from __future__ import annotations

import hashlib
import io
import os
import shutil
import socket
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

import league
from league.server.db.session import head_revision

from ..server.backends import TEST_SETTINGS, fresh_backend
from ..server.commands import REPO
from .semester import collect, differences, drained, semester
from .servers import LeagueServer, embedded_worker

# commit -> the schema revision its code writes: releases a course may upgrade from
RELEASES = {
    "7053bbc": "0017",  # the last 0.1.0: its workers register (the workers table, since 0014), its API does not
    "c4a0240": "0006",  # the last one before issues 22-26 (assignments, the database as the queue, ...)
    "b0d63d4": "0005",  # before the state stamp's indexes by kind
}
# how a release creates a league with an instructor (`league init` since 81d69d7; before it, any command did)
CREATE = {"7053bbc": ("init", "--instructor", "prof")}
FIRST_REGISTERING = "0014"  # releases from this schema list their workers: `league migrate` sees them
CORE_SOURCES = ("league/lidar.pyx", "league/constants.py", "setup.py")  # what league/lidar.*.so is built from
CORE_CACHE = Path("/tmp/league-release-cores")  # built cores of releases, kept between runs (by their sources)


def csv_rank(key: str) -> bool:
    return key == "rank"


def no_key(key: str) -> bool:
    return False


def core_sources(commit: str | None) -> bytes:
    """The sources of the compiled core at `commit` (None: this checkout)."""
    if commit is None:
        return b"".join((REPO / path).read_bytes() for path in CORE_SOURCES)
    return b"".join(subprocess.run(["git", "-C", str(REPO), "show", f"{commit}:{path}"], check=True,
                                   capture_output=True).stdout for path in CORE_SOURCES)


def release_tree(commit: str, folder: Path, cores: dict[bytes, Path]) -> Path:
    """The release's source tree, its simulator core compiled (or copied from a tree whose core's sources
    are the same: `cores`, by sources, holds the ones built so far)."""
    if subprocess.run(["git", "-C", str(REPO), "cat-file", "-e", f"{commit}^{{commit}}"]).returncode != 0:
        pytest.fail(f"commit {commit} is not in this clone: the upgrade test needs the history (git fetch --unshallow)")
    archive = subprocess.run(["git", "-C", str(REPO), "archive", "--format=tar", commit], check=True,
                             capture_output=True).stdout
    tree = folder / commit
    tree.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(tree, filter="data")
    sources = core_sources(commit)
    if sources not in cores:
        cores[sources] = cached_core(sources, tree)
    built = cores[sources]
    if built.parent != tree / "league":
        shutil.copy2(built, tree / "league" / built.name)
    return tree


def cached_core(sources: bytes, tree: Path) -> Path:
    """The core built from `sources` by this Python and Cython: from CORE_CACHE, or built in `tree`
    (setup.py build_ext, as a release is built) and kept there; written by rename, whole or not at all."""
    import Cython

    key = hashlib.sha256(sources + sys.version.encode() + Cython.__version__.encode()).hexdigest()[:32]
    kept = sorted((CORE_CACHE / key).glob("lidar.*.so"))
    if kept:
        return kept[0]
    subprocess.run([sys.executable, "setup.py", "build_ext", "--inplace"], cwd=tree, check=True, capture_output=True)
    built = next((tree / "league").glob("lidar.*.so"))
    (CORE_CACHE / key).mkdir(parents=True, exist_ok=True)
    partial = CORE_CACHE / key / f".{built.name}.{os.getpid()}"
    shutil.copy2(built, partial)
    partial.rename(CORE_CACHE / key / built.name)
    return built


@pytest.fixture(scope="module")
def releases(tmp_path_factory) -> dict[str, Path]:
    folder, cores = tmp_path_factory.mktemp("releases"), {}
    built_here = sorted((REPO / "league").glob("lidar.*.so"))
    if built_here:
        cores[core_sources(None)] = built_here[0]
    return {commit: release_tree(commit, folder, cores) for commit in RELEASES}


def registers(revision: str) -> bool:
    return int(revision) >= int(FIRST_REGISTERING)


# every migration since each release on both backends: PostgreSQL's from 0006, SQLite's (batch copies) from 0005;
# from 0017 (0.1.0) the unguarded order too: `league migrate` with the old server still running is refused
@pytest.mark.parametrize("commit, kind", [("c4a0240", "postgres"), ("b0d63d4", "sqlite"), ("7053bbc", "sqlite")])
def test_a_league_written_by_an_earlier_release_answers_the_same_after_the_upgrade(commit, kind, releases, tmp_path,
                                                                                   models):
    with fresh_backend(kind, tmp_path) as database_url:
        data_dir = tmp_path / "data"
        data_dir.mkdir()
        env = {**os.environ, **TEST_SETTINGS, "LEAGUE_DATA_DIR": str(data_dir), "LEAGUE_DATABASE_URL": database_url,
               "LEAGUE_CPU_SLOTS_DIR": str(tmp_path / "cpu-slots"), "LEAGUE_BASELINES_DIR": str(data_dir / "baselines")}
        old = LeagueServer({**env, "PYTHONPATH": str(releases[commit])}, data_dir, root=releases[commit])
        added = old.command(*CREATE.get(commit, ("users", "add", "prof", "--role", "instructor")))
        assert added.returncode == 0, added.stderr
        old.instructor_token = added.stdout.strip()
        new = LeagueServer({**env, "PYTHONPATH": str(REPO)}, data_dir, instructor_token=old.instructor_token)
        old.start_api()
        try:
            tokens = semester(old, models)
            drained(old)
            before = collect(old.url, old.instructor_token, tokens)
            if registers(RELEASES[commit]):  # the unguarded order: the old server still runs
                refused_under_it(new, embedded_worker(old.api))
        finally:
            old.stop_all()

        if RELEASES[commit] != head_revision():  # this code's workers do not run on the old schema
            refused = new.command("worker")
            assert refused.returncode == 2
            assert refused.stderr.splitlines()[-1] == (
                f"league: error: this database is at revision {RELEASES[commit]}, older than this installation's "
                f"{head_revision()}: run `league migrate` (back it up first: `league backup FILE`)")
        migrated = new.command("migrate")
        assert migrated.returncode == 0, migrated.stderr
        assert migrated.stderr.splitlines()[-1] in (
            f"league: migrated from schema revision {RELEASES[commit]} to {head_revision()}",
            f"league: already at schema revision {head_revision()}: nothing to do")
        new.start_api()
        try:
            after = collect(new.url, new.instructor_token, tokens)  # the old tokens still work, too
        finally:
            new.stop_all()
    assert before.keys() == after.keys()
    # the grade sheets rank among students since issue 23 (the baselines took ranks 1-6 before): their rows,
    # in the same order, are compared field by field but for the rank
    assert [d for path in before for d in differences(before[path], after[path], path, common_fields_only=True,
                                                      ignore=csv_rank if path.endswith(".csv") else no_key)] == []


def refused_under_it(new: LeagueServer, old_worker: int) -> None:
    """The new `league migrate` refuses, naming the old release's worker; so does a new `league serve`."""
    refused = new.command("migrate")
    assert refused.returncode == 2
    message = refused.stderr.splitlines()[-1]
    assert message.startswith(f"league: error: processes of another version than this one ({league.__version__}) "
                              f"use this database, and migrating under them would break them: alive: worker 0.1.0 "
                              f"on {socket.gethostname()}, pid {old_worker}, last heartbeat "), message
    assert message.endswith("Stop them first (every API and worker of the old version; with Docker: `docker "
                            "compose stop`)."), message
    serve = new.command("serve", "--port", "1")  # (it would migrate first: refused before it listens)
    served = serve.stderr.splitlines()[-1]
    assert serve.returncode == 2 and served.partition(", last heartbeat")[0] == message.partition(", last heartbeat")[0]
    assert served.endswith("Stop them first (every API and worker of the old version; with Docker: `docker compose "
                           "stop`)."), served
