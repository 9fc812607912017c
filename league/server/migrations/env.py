"""Alembic environment: migrations run programmatically (league.server.db.session.migrate: `league
serve`, `init`, `migrate`) or by hand with `alembic -c league/server/alembic.ini ...` (see there)."""
from alembic import context
from sqlalchemy import create_engine, pool

from league.server.core.config import load_settings
from league.server.db.models import Base, UTCDateTime
from league.server.db.session import migration_lock

config = context.config
target_metadata = Base.metadata


def render_item(type_, obj, autogen_context):
    """UTCDateTime is a Python-side conversion: the column is a plain DateTime."""
    if type_ == "type" and isinstance(obj, UTCDateTime):
        return "sa.DateTime()"
    return False


def run_migrations(connection) -> None:
    context.configure(connection=connection, target_metadata=target_metadata, render_item=render_item,
                      render_as_batch=connection.dialect.name == "sqlite")  # SQLite alters tables by copy
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    connection = config.attributes.get("connection")
    if connection is not None:
        run_migrations(connection)
        connection.commit()
        return
    engine = create_engine(_url(), poolclass=pool.NullPool)
    with migration_lock(engine) as connection:
        run_migrations(connection)
        connection.commit()


def _url() -> str:
    """`-x url=...`, else the league's own database (its LEAGUE_* settings), never a relative default."""
    return context.get_x_argument(as_dictionary=True).get("url") or load_settings().resolved_database_url


def run_migrations_offline() -> None:
    context.configure(url=_url(), target_metadata=target_metadata, literal_binds=True)
    with context.begin_transaction():
        context.run_migrations()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
