"""Engines, sessions and migrations, for SQLite (the embedded default) and PostgreSQL.

Only `league serve`, `league init` and `league migrate` change the schema (`migrate`, under a
lock); every other process opens the database with `open_engine`, which never creates one, and
refuses a schema other than its own (`schema_problem` says what to do).
"""
from __future__ import annotations

import contextlib
import fcntl
import functools
import os
from collections.abc import Callable, Iterator
from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, create_engine, event, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import DBAPIError
from sqlalchemy.orm import Session, sessionmaker

import league

MIGRATIONS_DIR = Path(__file__).resolve().parent.parent / "migrations"
PG_MIGRATION_LOCK = 7_305_512  # pg_advisory_lock key: API and workers may start at the same time
# A worker on another host whose link dies must notice within a minute, not the kernel's ~15 minutes:
# unacknowledged data times out after 30 s, an idle connection is probed every 10 s after 30 s.
PG_LINK_TIMEOUTS = {"connect_timeout": 10, "tcp_user_timeout": 30_000, "keepalives": 1, "keepalives_idle": 30,
                    "keepalives_interval": 10, "keepalives_count": 3}


class DatabaseError(Exception):
    """A database a command cannot use as it is; the message says what to do."""


SQLITE_POOL_SIZE = 20


def make_engine(url: str) -> Engine:
    if make_url(url).get_backend_name() == "sqlite":
        return _sqlite_engine(url)
    return create_engine(url, pool_pre_ping=True, pool_size=10, max_overflow=20, connect_args=PG_LINK_TIMEOUTS)


def _sqlite_engine(url: str) -> Engine:
    database = make_url(url).database
    if database and database != ":memory:":
        create_private_file(Path(database))
    # a pool as deep as the requests answered at once: beyond the default 5, each request opened, set up
    # (the pragmas above) and closed a connection of its own, which a status load at 200/s paid often
    engine = create_engine(url, pool_size=SQLITE_POOL_SIZE, connect_args={"timeout": 30, "check_same_thread": False})

    @event.listens_for(engine, "connect")
    def _pragmas(dbapi_connection, _record):  # WAL: the API reads while a worker writes
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute("PRAGMA busy_timeout=30000")
        # deleted rows are overwritten with zeros, not left in free pages: an erased student's data
        # (league.server.course.erasure) is gone from the file, not only from the tables
        cursor.execute("PRAGMA secure_delete=ON")
        cursor.close()

    return engine


def create_private_file(path: Path) -> None:
    """Create an SQLite file readable by its owner only, before SQLite does: its -wal and -shm files
    take the database file's permissions, so they are private too."""
    path.parent.mkdir(parents=True, exist_ok=True)
    os.close(os.open(path, os.O_CREAT | os.O_RDWR, 0o600))


def make_sessionmaker(engine: Engine) -> sessionmaker[Session]:
    return sessionmaker(engine, expire_on_commit=False)


def alembic_config(url: str) -> Config:
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    config.set_main_option("sqlalchemy.url", url.replace("%", "%%"))
    return config


def open_engine(url: str, *, setting: str, missing: str, create: bool = False) -> tuple[Engine, str | None]:
    """An engine on the league's database and its schema revision (None: no league in it yet).

    An SQLite file that does not exist is created only with `create` (else DatabaseError(`missing`):
    a command run from the wrong directory must not start a new, empty league); a database that
    does not answer raises DatabaseError naming `setting` and the host."""
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite" and not create and parsed.database not in (None, "", ":memory:") \
            and not Path(parsed.database).is_file():
        raise DatabaseError(missing)
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            return engine, revision_of(connection)
    except DBAPIError as error:
        engine.dispose()
        reason = " ".join(str(getattr(error, "orig", None) or error).split())
        raise DatabaseError(f"{setting}: cannot connect to {shown_url(url)}: {reason}") from None


def shown_url(url: str) -> str:
    return make_url(url).render_as_string(hide_password=True)


def revision_of(connection: Connection) -> str | None:
    return MigrationContext.configure(connection).get_current_revision()


def stored_revision(connection: Connection) -> str | None:
    """The revision alembic_version holds, read as a plain query: what running processes check at each
    beat (MigrationContext logs two lines each time it is made). A database error is raised, not taken
    for a changed schema: an outage must not stop a worker (its beat logs the failed pass and goes on)."""
    return connection.scalar(text("SELECT version_num FROM alembic_version"))


@functools.cache
def _scripts() -> ScriptDirectory:
    return ScriptDirectory.from_config(alembic_config(""))


def head_revision() -> str:
    return _scripts().get_current_head()


def schema_state(revision: str | None) -> str:
    """"current", "empty" (no league yet), "older" (run migrations) or "newer" (a newer installation's)."""
    if revision == head_revision():
        return "current"
    if revision is None:
        return "empty"
    return "older" if revision in {script.revision for script in _scripts().walk_revisions()} else "newer"


def schema_problem(revision: str | None) -> str | None:
    """None if a database at `revision` is this installation's schema, else what to do about it."""
    head = head_revision()
    return {
        "current": None,
        "empty": "this database holds no league yet: `league init` creates one",
        "older": f"this database is at revision {revision}, older than this installation's {head}: run "
                 f"`league migrate` (back it up first: `league backup FILE`)",
        "newer": f"this database is at revision {revision}, written by a newer version of microracer-league "
                 f"(this one, {league.__version__}, knows revisions up to {head}): upgrade this installation",
    }[schema_state(revision)]


def check_schema(revision: str | None) -> None:
    problem = schema_problem(revision)
    if problem:
        raise DatabaseError(problem)


def migrate(engine: Engine, *, new_only: bool = False, to: str = "head",
            guard: Callable[[Connection], None] | None = None) -> tuple[str | None, str]:
    """`alembic upgrade head` (or up or down `to` a revision), serialised between processes that start
    together; (from, to) revisions. With `new_only` (`league init`) a database of an older schema is
    refused instead. `guard(connection)` may refuse before anything changes (processes of another
    version run: league.server.jobs.registry). The revision is read under the lock: one read before it
    may see another process's migration half done."""
    with migration_lock(engine) as connection:
        before = revision_of(connection)
        if schema_state(before) == "newer" or (new_only and schema_state(before) == "older"):
            raise DatabaseError(schema_problem(before))
        target = head_revision() if to == "head" else to
        if target != before and guard is not None:
            guard(connection)
        connection.commit()  # (reading the revision began a transaction)
        if to == "head" or is_later(to, before):
            upgrade(connection, to)
        elif to != before:
            downgrade(connection, to)
        return before, revision_of(connection)


def known_revision(revision: str) -> str:
    """`revision` if a migration of this installation has it, else DatabaseError listing them."""
    known = [script.revision for script in _scripts().walk_revisions()]
    if revision not in known:
        raise DatabaseError(f"no schema revision {revision!r} here: this installation knows "
                            f"{', '.join(reversed(known))}")
    return revision


def is_later(revision: str, than: str | None) -> bool:
    """Whether `revision` comes after `than` in the migrations' chain (None: before them all)."""
    return than is None or than in {script.revision for script in _scripts().iterate_revisions(revision, "base")
                                    if script.revision != revision}


def downgrade(connection: Connection, revision: str) -> None:
    """`alembic downgrade REVISION` on this connection (committed); the migrations' downgrade() steps."""
    config = alembic_config(connection.engine.url.render_as_string(hide_password=False))
    config.attributes["connection"] = connection
    command.downgrade(config, revision)


def upgrade(connection: Connection, revision: str) -> None:
    """`alembic upgrade REVISION` on this connection (committed); no lock: `migrate` takes it."""
    config = alembic_config(connection.engine.url.render_as_string(hide_password=False))
    config.attributes["connection"] = connection
    command.upgrade(config, revision)


@contextlib.contextmanager
def migration_lock(engine: Engine) -> Iterator:
    if engine.dialect.name == "postgresql":
        with engine.connect() as connection:
            connection.execute(text("SELECT pg_advisory_lock(:key)"), {"key": PG_MIGRATION_LOCK})
            connection.commit()
            try:
                yield connection
            finally:
                connection.execute(text("SELECT pg_advisory_unlock(:key)"), {"key": PG_MIGRATION_LOCK})
                connection.commit()
        return
    lock_path = Path(engine.url.database or "league.db").with_suffix(".migrate.lock")
    create_private_file(lock_path)
    with open(lock_path, "w") as lock_file, engine.connect() as connection:
        fcntl.flock(lock_file, fcntl.LOCK_EX)
        yield connection
