"""student_assignments: a final frozen at the close time keeps its candidates (the student's uploads
then) until each is validated and evaluated on the public tracks, when the final is decided
(`final_decided_at`); `published_evaluation_id` is the private result a grade had at publication,
so that a grade can say it changed since. Finals frozen before this revision were decided when frozen.

Revision ID: 0018
Revises: 0017
Create Date: 2026-11-28 09:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0018'
down_revision = '0017'
branch_labels = None
depends_on = None

COLUMNS = ('final_candidates', 'final_decided_at', 'published_evaluation_id')


def upgrade() -> None:
    op.add_column('student_assignments', sa.Column('final_candidates', sa.JSON(), nullable=True))
    op.add_column('student_assignments', sa.Column('final_decided_at', sa.DateTime(), nullable=True))
    op.add_column('student_assignments', sa.Column('published_evaluation_id', sa.Integer(), nullable=True))
    op.execute('UPDATE student_assignments SET final_decided_at = final_at WHERE final_at IS NOT NULL')
    op.execute('UPDATE student_assignments SET published_evaluation_id = final_evaluation_id WHERE assignment_id IN '
               '(SELECT id FROM assignments WHERE published_at IS NOT NULL)')


def downgrade() -> None:
    for column in reversed(COLUMNS):
        op.drop_column('student_assignments', column)  # SQLite >= 3.35 drops a column in place
