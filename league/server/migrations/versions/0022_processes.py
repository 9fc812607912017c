"""workers.kind: the table lists every league process, API ("api") and workers ("worker"), with its
version and heartbeat, so that `league migrate` can refuse while processes of another version run
and /api/health counts the workers only. Existing rows are workers (the only processes it held).

Revision ID: 0022
Revises: 0021
Create Date: 2026-11-28 09:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0022'
down_revision = '0021'
branch_labels = None
depends_on = None


def upgrade() -> None:
    # in place on SQLite too (a column with a constant default): no batch copy of a table others write
    op.add_column('workers', sa.Column('kind', sa.String(length=10), nullable=False, server_default='worker'))


def downgrade() -> None:
    op.execute("DELETE FROM workers WHERE kind <> 'worker'")  # the older schema lists workers only
    op.drop_column('workers', 'kind')  # SQLite >= 3.35 drops a column in place
