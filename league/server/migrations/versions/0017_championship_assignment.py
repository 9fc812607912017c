"""championships.assignment_id: a championship may belong to an assignment (its rounds race each
student's final choice there); existing championships belong to none and keep racing the students'
active submissions

Revision ID: 0017
Revises: 0014
Create Date: 2026-11-25 20:30:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0017'
down_revision = '0014'
branch_labels = None
depends_on = None


def upgrade() -> None:
    # in place, as 0010's add_reference: a batch copy of championships is refused by the foreign keys to it
    if op.get_bind().dialect.name == 'sqlite':
        op.execute('ALTER TABLE championships ADD COLUMN assignment_id INTEGER REFERENCES assignments (id)')
    else:
        op.add_column('championships', sa.Column('assignment_id', sa.Integer(), sa.ForeignKey('assignments.id'),
                                                 nullable=True))


def downgrade() -> None:
    op.drop_column('championships', 'assignment_id')  # SQLite >= 3.35 drops a column in place
