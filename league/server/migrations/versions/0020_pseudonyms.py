"""users.pseudonym: the public boards' "Student N" drawn at random for each user of a course (unique
in it), instead of a keyed permutation of the user id that one board let anyone invert

Existing users of a course get theirs here, drawn with `secrets`, distinct within the course.

Revision ID: 0020
Revises: 0018
Create Date: 2026-11-28 09:30:00
"""
import secrets

import sqlalchemy as sa
from alembic import op


revision = '0020'
down_revision = '0018'
branch_labels = None
depends_on = None

PSEUDONYMS = 999_999  # league.server.course.privacy.PSEUDONYMS, as it was at this revision


def upgrade() -> None:
    op.add_column('users', sa.Column('pseudonym', sa.Integer(), nullable=True))
    connection = op.get_bind()
    rows = connection.execute(sa.text("SELECT id, course_id FROM users WHERE course_id IS NOT NULL")).all()
    taken: dict[int, set[int]] = {}
    for user_id, course_id in rows:
        used = taken.setdefault(course_id, set())
        number = 1 + secrets.randbelow(PSEUDONYMS)
        while number in used:
            number = 1 + secrets.randbelow(PSEUDONYMS)
        used.add(number)
        connection.execute(sa.text("UPDATE users SET pseudonym = :number WHERE id = :id"),
                           {"number": number, "id": user_id})
    op.create_index('uq_users_course_pseudonym', 'users', ['course_id', 'pseudonym'], unique=True)


def downgrade() -> None:
    op.drop_index('uq_users_course_pseudonym', 'users')
    op.drop_column('users', 'pseudonym')  # SQLite >= 3.35 drops a column in place
