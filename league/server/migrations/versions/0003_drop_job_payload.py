"""drop jobs.payload (never written: a job's subject is in its foreign keys)

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-23 17:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0003'
down_revision = '0002'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('jobs') as batch:  # SQLite rebuilds the table
        batch.drop_column('payload')


def downgrade() -> None:
    with op.batch_alter_table('jobs') as batch:
        batch.add_column(sa.Column('payload', sa.JSON(), nullable=False, server_default='{}'))
