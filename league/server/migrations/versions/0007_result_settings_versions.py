"""results carry what produced them: evaluations.result_key (the settings and the simulator's
version; boards rank only the current key) and evaluations.versions / races.versions (physics,
track format, package); jobs.priority (the re-evaluations a settings change queues wait for the
students' jobs)

Existing evaluations are keyed from their stored settings with this revision's simulator (physics
1, track format 1), which produced them, so nothing is re-ranked; finished ones and finished races
get its versions (the package has been 0.1.0 throughout).

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-26 10:00:00
"""
import hashlib
import json

import sqlalchemy as sa
from alembic import op


revision = '0007'
down_revision = '0006'
branch_labels = None
depends_on = None

# frozen as they were at this revision: what league.evaluation.result_key computed then
VERSIONS = {"physics": 1, "track_format": 1, "package": "0.1.0"}
DEFAULT_OPTIONS = {"obstacles": True, "chicanes": True, "turn_limit": True, "low_speed_termination": True,
                   "curves": 20, "track_width": 0.04, "n_obstacles": 6, "tstep": 0.04, "max_episode_steps": 4000}


def result_key(settings: dict) -> str:
    given = settings.get("env_options") or {}
    try:
        options = {name: None if given.get(name, default) is None else type(default)(given.get(name, default))
                   for name, default in DEFAULT_OPTIONS.items()}
        if set(given) - set(DEFAULT_OPTIONS):
            raise ValueError("an option the simulator does not know")
        what = {"seed": int(settings["seed"]), "episodes": int(settings["episodes"]), "env_options": options,
                "physics": VERSIONS["physics"], "track_format": VERSIONS["track_format"]}
    except (KeyError, TypeError, ValueError):  # settings the simulator refuses: a key of their own text
        return hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode()).hexdigest()[:16]
    return hashlib.sha256(json.dumps(what, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:16]


def upgrade() -> None:
    # plain ALTER TABLE (no batch copy, also on SQLite): a copy of evaluations would be refused by the
    # foreign keys of its episodes and jobs; hence result_key stays nullable in the schema
    op.add_column('jobs', sa.Column('priority', sa.Integer(), server_default=sa.text('0'), nullable=False))
    op.add_column('races', sa.Column('versions', sa.JSON(), nullable=True))
    op.add_column('evaluations', sa.Column('result_key', sa.String(length=16), nullable=True))
    op.add_column('evaluations', sa.Column('versions', sa.JSON(), nullable=True))
    key_evaluations(op.get_bind())
    op.create_index('ix_evaluations_key_status_submission', 'evaluations', ['result_key', 'status', 'submission_id'])


def key_evaluations(connection) -> None:
    evaluations = sa.table('evaluations', sa.column('id', sa.Integer), sa.column('settings', sa.JSON),
                           sa.column('status', sa.String), sa.column('result_key', sa.String),
                           sa.column('versions', sa.JSON))
    races = sa.table('races', sa.column('status', sa.String), sa.column('versions', sa.JSON))
    keys: dict[str, list[int]] = {}
    for evaluation_id, settings in connection.execute(sa.select(evaluations.c.id, evaluations.c.settings)):
        keys.setdefault(result_key(settings), []).append(evaluation_id)
    for key, ids in keys.items():  # one UPDATE per distinct settings (a course has had a few)
        for first in range(0, len(ids), 500):
            connection.execute(evaluations.update().where(evaluations.c.id.in_(ids[first:first + 500]))
                               .values(result_key=key))
    connection.execute(evaluations.update().where(evaluations.c.status == 'done').values(versions=VERSIONS))
    connection.execute(races.update().where(races.c.status == 'done').values(versions=VERSIONS))


def downgrade() -> None:
    op.drop_index('ix_evaluations_key_status_submission', 'evaluations')
    for table, column in (('evaluations', 'versions'), ('evaluations', 'result_key'), ('races', 'versions'),
                          ('jobs', 'priority')):
        op.drop_column(table, column)  # SQLite >= 3.35 drops a column in place
