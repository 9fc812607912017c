"""workers: each running worker process and its last heartbeat, so that /api/health can say
whether queued jobs have a worker to run them (the database is the job queue from this revision)

Revision ID: 0014
Revises: 0016
Create Date: 2026-11-25 19:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0014'
down_revision = "0016"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'workers',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('host', sa.String(length=255), nullable=False),
        sa.Column('pid', sa.Integer(), nullable=False),
        sa.Column('version', sa.String(length=50), nullable=False),
        sa.Column('started_at', sa.DateTime(), nullable=False),
        sa.Column('heartbeat_at', sa.DateTime(), nullable=False),
        sa.PrimaryKeyConstraint('id'),
    )
    op.create_index('ix_workers_heartbeat_at', 'workers', ['heartbeat_at'])


def downgrade() -> None:
    op.drop_index('ix_workers_heartbeat_at', 'workers')
    op.drop_table('workers')
