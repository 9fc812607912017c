"""races, championships, active submissions

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-23 04:30:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0002'
down_revision = '0001'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('users', sa.Column('active_submission_id', sa.Integer(), nullable=True))
    op.create_table('championships',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('course_id', sa.Integer(), nullable=True),
    sa.Column('name', sa.String(length=100), nullable=False),
    sa.Column('env_options', sa.JSON(), nullable=False),
    sa.Column('heat_size', sa.Integer(), nullable=False),
    sa.Column('points', sa.JSON(), nullable=False),
    sa.Column('include_baselines', sa.Boolean(), nullable=False),
    sa.Column('seed', sa.BigInteger(), nullable=False),
    sa.Column('created_by_id', sa.Integer(), nullable=True),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['course_id'], ['courses.id'], ),
    sa.ForeignKeyConstraint(['created_by_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id')
    )
    op.create_index('ix_championships_course_id', 'championships', ['course_id'])
    op.create_table('championship_rounds',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('championship_id', sa.Integer(), nullable=False),
    sa.Column('number', sa.Integer(), nullable=False),
    sa.Column('track_seed', sa.BigInteger(), nullable=False),
    sa.Column('heats', sa.JSON(), nullable=False),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['championship_id'], ['championships.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('championship_id', 'number')
    )
    op.create_table('races',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('course_id', sa.Integer(), nullable=True),
    sa.Column('created_by_id', sa.Integer(), nullable=True),
    sa.Column('championship_id', sa.Integer(), nullable=True),
    sa.Column('round_id', sa.Integer(), nullable=True),
    sa.Column('heat', sa.Integer(), nullable=True),
    sa.Column('seed', sa.BigInteger(), nullable=False),
    sa.Column('env_options', sa.JSON(), nullable=False),
    sa.Column('entrants', sa.JSON(), nullable=False),
    sa.Column('status', sa.String(length=20), nullable=False),
    sa.Column('error', sa.Text(), nullable=True),
    sa.Column('log', sa.Text(), nullable=True),
    sa.Column('classification', sa.JSON(), nullable=True),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.Column('started_at', sa.DateTime(), nullable=True),
    sa.Column('finished_at', sa.DateTime(), nullable=True),
    sa.ForeignKeyConstraint(['course_id'], ['courses.id'], ),
    sa.ForeignKeyConstraint(['created_by_id'], ['users.id'], ),
    sa.ForeignKeyConstraint(['championship_id'], ['championships.id'], ),
    sa.ForeignKeyConstraint(['round_id'], ['championship_rounds.id'], ),
    sa.PrimaryKeyConstraint('id')
    )
    op.create_index('ix_races_status', 'races', ['status'])
    op.create_index('ix_races_championship_id', 'races', ['championship_id'])
    op.create_index('ix_races_round_id', 'races', ['round_id'])
    op.create_index('ix_races_creator_created', 'races', ['created_by_id', 'created_at'])
    op.create_table('race_replays',
    sa.Column('race_id', sa.Integer(), nullable=False),
    sa.Column('data', sa.LargeBinary(), nullable=False),
    sa.ForeignKeyConstraint(['race_id'], ['races.id'], ),
    sa.PrimaryKeyConstraint('race_id')
    )
    with op.batch_alter_table('jobs') as batch:
        batch.add_column(sa.Column('race_id', sa.Integer(), nullable=True))
        batch.create_foreign_key('fk_jobs_race_id', 'races', ['race_id'], ['id'])
        batch.create_index('ix_jobs_race_id', ['race_id'])


def downgrade() -> None:
    with op.batch_alter_table('jobs') as batch:
        batch.drop_index('ix_jobs_race_id')
        batch.drop_constraint('fk_jobs_race_id', type_='foreignkey')
        batch.drop_column('race_id')
    op.drop_table('race_replays')
    op.drop_table('races')
    op.drop_table('championship_rounds')
    op.drop_index('ix_championships_course_id', 'championships')
    op.drop_table('championships')
    op.drop_column('users', 'active_submission_id')
