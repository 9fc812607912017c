"""privacy of the boards: courses.board_visibility (public, members or instructors) and
courses.pseudonym_key (the public boards' "Student N"); users.display_name, unique in a course

Existing courses stay public, as they were (an upgrade changes nothing silently; new courses take
LEAGUE_BOARD_VISIBILITY, by default members); each gets a random pseudonym key.

Revision ID: 0012
Revises: 0013
Create Date: 2026-11-25 19:00:00
"""
import secrets

import sqlalchemy as sa
from alembic import op


revision = '0012'
down_revision = '0013'  # main's head (0013 follows 0015)
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('courses', sa.Column('board_visibility', sa.String(length=20), nullable=False,
                                       server_default='public'))
    op.add_column('courses', sa.Column('pseudonym_key', sa.BigInteger(), nullable=True))
    connection = op.get_bind()
    for (course_id,) in connection.execute(sa.text("SELECT id FROM courses")).all():
        connection.execute(sa.text("UPDATE courses SET pseudonym_key = :key WHERE id = :id"),
                           {"key": secrets.randbits(62), "id": course_id})
    op.add_column('users', sa.Column('display_name', sa.String(length=100), nullable=True))
    op.create_index('uq_users_course_display_name', 'users', ['course_id', 'display_name'], unique=True)


def downgrade() -> None:
    op.drop_index('uq_users_course_display_name', 'users')
    # in place (SQLite >= 3.35), as 0008: a batch copy is refused by the foreign keys to these tables
    op.drop_column('users', 'display_name')
    op.drop_column('courses', 'pseudonym_key')
    op.drop_column('courses', 'board_visibility')
