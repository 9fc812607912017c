"""assignments.rubric: the grading rubric an instructor sets (league.server.course.grading: JSON, checked
when set); existing assignments have none until one is set

Revision ID: 0016
Revises: 0010
Create Date: 2026-11-25 20:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0016'
down_revision = '0010'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('assignments', sa.Column('rubric', sa.JSON(), nullable=True))


def downgrade() -> None:
    # in place (SQLite >= 3.35), as 0008: a batch copy of assignments is refused by the foreign keys to it
    op.drop_column('assignments', 'rubric')
