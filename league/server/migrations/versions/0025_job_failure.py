"""jobs.failure: why a failed job failed, in one word of models.FAILURES (the metrics count failures by it;
`error` keeps the whole reason). Jobs that failed before it say nothing: NULL, counted as "unrecorded".

Revision ID: 0025
Revises: 0024
Create Date: 2026-11-28 09:30:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0025'
down_revision = '0024'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('jobs', sa.Column('failure', sa.String(20), nullable=True))


def downgrade() -> None:
    op.drop_column('jobs', 'failure')  # SQLite >= 3.35 drops a column in place
