"""submissions.probe_key and submissions.probe_actions: each submission's actions on the toolkit's
probe set (league.validation.probes), recorded in its validation's sandbox, which the integrity
report compares. Existing submissions keep both empty: the report lists them as not yet probed
until an instructor has them probed (POST /api/integrity/probe)

Revision ID: 0013
Revises: 0015
Create Date: 2026-11-25 19:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0013'
down_revision = '0015'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('submissions', sa.Column('probe_key', sa.String(length=16), nullable=True))
    op.add_column('submissions', sa.Column('probe_actions', sa.LargeBinary(), nullable=True))


def downgrade() -> None:
    # in place (SQLite >= 3.35), as 0007: a batch copy of submissions is refused by the foreign keys to it
    op.drop_column('submissions', 'probe_actions')
    op.drop_column('submissions', 'probe_key')
