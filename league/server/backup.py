"""`league backup FILE` and `league restore FILE`: the league's whole state, its database, in one file.

The database is the state: users and tokens (hashed), submissions and their model files (`blobs`),
evaluations, jobs, races and their replays (`race_replays`), championships. The data directory
holds only copies a worker fetches from the database again (`blobs/`).

One format for both backends: a backup is an SQLite database with the league's schema at the
revision of the database it was taken from, readable with `sqlite3 FILE`. It is a consistent
snapshot taken while the server runs:

* SQLite: SQLite's online backup API copies the file in one step, one read transaction (in WAL
  mode writers go on meanwhile);
* PostgreSQL: every table is read in one REPEATABLE READ, READ ONLY transaction (one snapshot)
  into an SQLite file migrated to the same revision.

A restore goes into a fresh data directory or an empty database (`replace`: over an existing one)
of either backend, migrated to this installation's schema; jobs that were running at the backup
go back to the queue (their workers are gone) and, as the queued ones, run as soon as a worker
looks (the jobs table is the queue), and the backed-up list of workers is emptied. Every file
written, temporary or not, is readable by its owner only.
"""
from __future__ import annotations

import contextlib
import os
import sqlite3
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from sqlalchemy import Connection, Engine, LargeBinary, MetaData, create_engine, func, select, text
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session

from league.server.db.session import (
    make_engine, migrate, schema_problem, schema_state, shown_url, upgrade,
)
from league.server.jobs.leases import release_running
from league.server.jobs.registry import forget_all

ROWS_PER_BATCH = 1000
BLOBS_PER_BATCH = 16  # rows holding model files or replays (up to LEAGUE_MAX_UPLOAD_MB each)
COUNTED = ("users", "submissions", "evaluations", "races", "jobs")  # shown in the report


class BackupError(Exception):
    """A backup or restore that cannot be made as asked; the message says what to do."""


@dataclass
class Report:
    revision: str
    counts: dict[str, int]  # rows of the COUNTED tables
    size: int  # bytes of the backup file
    seconds: float

    def summary(self) -> str:
        counts = ", ".join(f"{n} {table}" for table, n in self.counts.items())
        return f"{counts} (schema revision {self.revision}, {self.size / 2**20:.1f} MB, {self.seconds:.1f} s)"


# --------------------------------------------------------------------------- backup


def backup(engine: Engine, revision: str | None, path: Path) -> Report:
    """Write a consistent snapshot of the league's database to `path` (replaced atomically)."""
    if schema_state(revision) in ("empty", "newer"):
        raise BackupError(schema_problem(revision))
    started, path = time.monotonic(), Path(path).absolute()
    if not path.parent.is_dir():
        raise BackupError(f"cannot write {path}: the folder {path.parent} does not exist")
    with _private_files(), _temporary(path.parent, f".{path.name}.") as partial:
        if engine.dialect.name == "sqlite":
            _sqlite_snapshot(Path(engine.url.database), partial)
        else:
            _export(engine, revision, partial)
        _seal(partial)
        os.replace(partial, path)
    return _report(path, time.monotonic() - started)


def _sqlite_snapshot(database: Path, destination: Path, *, read_only: bool = False) -> None:
    """SQLite's online backup, all pages in one step: one read transaction, so one consistent state
    (a live database in WAL mode goes on taking writes meanwhile)."""
    source_uri = f"file:{Path(database).absolute()}{'?mode=ro' if read_only else ''}"
    with contextlib.closing(sqlite3.connect(source_uri, uri=True, timeout=30)) as source, \
            contextlib.closing(sqlite3.connect(destination)) as copy:
        source.backup(copy)


def _export(engine: Engine, revision: str, destination: Path) -> None:
    """Every table of a PostgreSQL league, read in one snapshot, into an SQLite file of the same revision."""
    copy = create_engine(f"sqlite:///{destination}")
    try:
        with copy.connect() as target:
            upgrade(target, revision)
        snapshot = engine.connect().execution_options(isolation_level="REPEATABLE READ", postgresql_readonly=True)
        with snapshot as source, copy.begin() as target:
            copy_tables(source, target)
    finally:
        copy.dispose()


def _seal(path: Path) -> None:
    """A self-contained file (no -wal beside it), checked before it replaces the previous backup."""
    with contextlib.closing(sqlite3.connect(path)) as connection:
        connection.execute("PRAGMA journal_mode=DELETE")
        problems = connection.execute("PRAGMA quick_check").fetchall()
    if problems != [("ok",)]:
        raise BackupError(f"the backup failed its integrity check: {problems[:3]}")
    with open(path, "rb+") as handle:
        os.fsync(handle.fileno())


def _report(path: Path, seconds: float) -> Report:
    with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as connection:
        revision = connection.execute("SELECT version_num FROM alembic_version").fetchone()[0]
        present = {name for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        counts = {table: connection.execute(f'SELECT count(*) FROM "{table}"').fetchone()[0]
                  for table in COUNTED if table in present}  # the first schema had no races (0002)
    return Report(revision, counts, path.stat().st_size, seconds)


# --------------------------------------------------------------------------- restore


def backup_revision(path: Path) -> str:
    """The schema revision of a backup file, after checking it is one this installation can restore."""
    if not Path(path).is_file():
        raise BackupError(f"no such backup file: {path}")
    try:
        with contextlib.closing(sqlite3.connect(f"file:{Path(path).absolute()}?mode=ro", uri=True)) as connection:
            intact = connection.execute("PRAGMA quick_check").fetchall() == [("ok",)]
            revision = connection.execute("SELECT version_num FROM alembic_version").fetchone()
    except sqlite3.DatabaseError as error:
        raise BackupError(f"{path} is not a league backup (written by `league backup`): {error}") from None
    if not intact or revision is None:
        raise BackupError(f"{path} is damaged: it fails SQLite's integrity check or names no schema revision")
    if schema_state(revision[0]) == "newer":
        raise BackupError(f"{path}: {schema_problem(revision[0])}")
    return revision[0]


def restore(path: Path, url: str, *, replace: bool = False) -> Report:
    """Restore a backup into the database at `url` (empty, or `replace`d), at this installation's schema."""
    started, revision = time.monotonic(), backup_revision(path)
    if not replace and holds_league(url):
        raise BackupError(f"{shown_url(url)} already holds a league: restore into a fresh data directory or an "
                          f"empty database, or give --replace to overwrite it (stop its server and workers first)")
    with _private_files():
        if make_url(url).get_backend_name() == "sqlite":
            _restore_sqlite(Path(path), Path(make_url(url).database))
        else:
            _restore_postgres(Path(path), url, replace)
    report = _report(Path(path), time.monotonic() - started)
    report.revision = revision
    return report


def holds_league(url: str) -> bool:
    """Whether any table of the database has a row (an empty schema, as `league migrate` leaves it, does not)."""
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite" and not Path(parsed.database).is_file():
        return False
    engine = create_engine(url)
    try:
        with engine.connect() as connection:
            tables = MetaData()
            tables.reflect(connection)
            return any(connection.scalar(select(func.count()).select_from(table))
                       for name, table in tables.tables.items() if name != "alembic_version")
    finally:
        engine.dispose()


def _restore_sqlite(path: Path, database: Path) -> None:
    """Copy the backup next to the database, migrate and release it there, then move it into place."""
    database.parent.mkdir(parents=True, exist_ok=True)
    with _temporary(database.parent, f".{database.name}.restore-") as copy:
        _sqlite_snapshot(path, copy, read_only=True)
        engine = create_engine(f"sqlite:///{copy}")
        try:
            with engine.connect() as connection:
                upgrade(connection, "head")
            with Session(engine) as session, session.begin():
                release_running(session, reason="restored from a backup taken while it ran")
                forget_all(session)
        finally:
            engine.dispose()
        for stale in (database.with_name(database.name + "-wal"), database.with_name(database.name + "-shm")):
            stale.unlink(missing_ok=True)  # SQLite would apply an old journal to the new file
        os.replace(copy, database)


def _restore_postgres(path: Path, url: str, replace: bool) -> None:
    """Migrate a private copy of the backup to this schema, then copy its rows in one transaction."""
    with tempfile.TemporaryDirectory(prefix="league-restore-") as folder:
        copy = Path(folder) / "restore.db"
        _sqlite_snapshot(path, copy, read_only=True)
        source, engine = create_engine(f"sqlite:///{copy}"), make_engine(url)
        try:
            with source.connect() as connection:
                upgrade(connection, "head")
            if replace:
                _drop_tables(engine)
            migrate(engine)
            with source.connect() as rows, Session(engine) as session, session.begin():
                copy_tables(rows, session.connection())
                _restart_sequences(session.connection())
                release_running(session, reason="restored from a backup taken while it ran")
                forget_all(session)
        finally:
            source.dispose()
            engine.dispose()


def _drop_tables(engine: Engine) -> None:
    """Every table of the database: --replace replaces the whole database."""
    with engine.begin() as connection:
        tables = MetaData()
        tables.reflect(connection)
        tables.drop_all(connection)


def _restart_sequences(connection: Connection) -> None:
    """PostgreSQL's id sequences continue after the restored rows."""
    tables = MetaData()
    tables.reflect(connection)
    for table in tables.tables.values():
        keys = list(table.primary_key.columns)
        if len(keys) == 1 and keys[0].type.python_type is int:
            connection.execute(text("SELECT setval(pg_get_serial_sequence(:table, :column), "
                                    f'coalesce((SELECT max("{keys[0].name}") FROM "{table.name}"), 0) + 1, false)'),
                               {"table": table.name, "column": keys[0].name})


# --------------------------------------------------------------------------- shared


def copy_tables(source: Connection, target: Connection) -> None:
    """Every row of every table (but alembic's) from `source` into the same, empty tables of `target`,
    parents first, in batches; the two schemas must be at the same revision."""
    theirs, ours = MetaData(), MetaData()
    theirs.reflect(source)
    ours.reflect(target)
    for table in ours.sorted_tables:
        if table.name == "alembic_version":
            continue
        origin = theirs.tables.get(table.name)
        if origin is None or set(origin.columns.keys()) != set(table.columns.keys()):
            raise BackupError(f"table {table.name} differs between the backup and the database: "
                                f"not the same schema revision")
        columns = [origin.columns[name] for name in table.columns.keys()]
        batch = BLOBS_PER_BATCH if any(isinstance(c.type, LargeBinary) for c in table.columns) else ROWS_PER_BATCH
        rows = source.execution_options(yield_per=batch).execute(
            select(*columns).order_by(*origin.primary_key.columns))
        for partition in rows.mappings().partitions():
            target.execute(table.insert(), [dict(row) for row in partition])


@contextlib.contextmanager
def _private_files() -> Iterator[None]:
    """Files created meanwhile (SQLite's journals too) are readable by their owner only."""
    previous = os.umask(0o077)
    try:
        yield
    finally:
        os.umask(previous)


@contextlib.contextmanager
def _temporary(folder: Path, prefix: str) -> Iterator[Path]:
    """A new private file in `folder` (beside its destination: moved into place atomically), removed
    with its SQLite journal unless it was moved."""
    handle, name = tempfile.mkstemp(dir=folder, prefix=prefix)
    os.close(handle)
    path = Path(name)
    try:
        yield path
    finally:
        for leftover in (path, path.with_name(path.name + "-journal")):
            leftover.unlink(missing_ok=True)
