"""users.email and users.student_id, from rosters, so that gradebook exports (Canvas, Moodle) can
identify students; a student id is unique within its course when given. Existing users keep both
empty (an instructor fills them in by uploading the roster again)

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-26 10:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0008'
down_revision = '0007'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('users', sa.Column('email', sa.String(length=254), nullable=True))
    op.add_column('users', sa.Column('student_id', sa.String(length=64), nullable=True))
    op.create_index('uq_users_course_student_id', 'users', ['course_id', 'student_id'], unique=True)


def downgrade() -> None:
    op.drop_index('uq_users_course_student_id', 'users')
    # in place (SQLite >= 3.35), as 0007: a batch copy of users is refused by the foreign keys to it
    op.drop_column('users', 'student_id')
    op.drop_column('users', 'email')
