"""The schema: the Alembic migrations build exactly what the models describe, on both backends."""
from __future__ import annotations

from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import inspect

from league.server.db.models import Base
from league.server.db.session import alembic_config, make_engine, migrate


def test_migrations_match_the_models_and_run_twice(backend):
    _, (database_url, _, _) = backend
    engine = make_engine(database_url)
    migrate(engine)
    migrate(engine)  # a second start finds the schema up to date
    with engine.connect() as connection:
        diff = compare_metadata(MigrationContext.configure(connection), Base.metadata)
        tables = set(inspect(connection).get_table_names())
    engine.dispose()
    assert diff == []
    assert {"courses", "users", "submissions", "evaluations", "episode_results", "jobs", "races", "race_replays",
            "championships", "championship_rounds", "alembic_version"} <= tables


def test_downgrade_to_nothing_and_back(backend):
    _, (database_url, _, _) = backend
    engine = make_engine(database_url)
    migrate(engine)
    config = alembic_config(database_url)
    with engine.connect() as connection:
        config.attributes["connection"] = connection
        command.downgrade(config, "base")
        assert set(inspect(connection).get_table_names()) <= {"alembic_version"}
    migrate(engine)
    with engine.connect() as connection:
        assert "jobs" in inspect(connection).get_table_names()
    engine.dispose()
