"""assignments.automatic and assignments.keep_open: a course's automatic assignment ("default", made
with the course) takes no more uploads once the course has an assignment of its instructors', unless
they keep it open (league.server.course.assignments.retired)

automatic: each course's oldest assignment named "default" (the one 0010 or the course's creation
made). keep_open: an upgrade changes nothing silently (as 0012 kept existing boards public): in a
course that already has assignments of its instructors, the automatic one stays open as before,
until an instructor closes it (console: Assignments; `league assignments edit default --no-keep-open`);
elsewhere it closes when the first such assignment is created, as in a new course.

Revision ID: 0021
Revises: 0020
Create Date: 2026-11-28 09:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0021'
down_revision = '0020'
branch_labels = None
depends_on = None

DEFAULT_ASSIGNMENT = "default"


def upgrade() -> None:
    op.add_column('assignments', sa.Column('automatic', sa.Boolean(), nullable=False, server_default=sa.false()))
    op.add_column('assignments', sa.Column('keep_open', sa.Boolean(), nullable=False, server_default=sa.false()))
    assignments = sa.table('assignments', sa.column('id', sa.Integer), sa.column('course_id', sa.Integer),
                           sa.column('name', sa.String), sa.column('automatic', sa.Boolean),
                           sa.column('keep_open', sa.Boolean))
    connection = op.get_bind()
    oldest = {}
    for assignment_id, course_id, name in connection.execute(
            sa.select(assignments.c.id, assignments.c.course_id, assignments.c.name).order_by(assignments.c.id)):
        oldest.setdefault(course_id, (assignment_id, name))
    courses_with_more = {course_id for (course_id,) in connection.execute(
        sa.select(assignments.c.course_id).group_by(assignments.c.course_id).having(sa.func.count() > 1))}
    for course_id, (assignment_id, name) in oldest.items():
        if name == DEFAULT_ASSIGNMENT:
            connection.execute(assignments.update().where(assignments.c.id == assignment_id)
                               .values(automatic=True, keep_open=course_id in courses_with_more))


def downgrade() -> None:
    # in place (SQLite >= 3.35), as 0016: a batch copy of assignments is refused by the foreign keys to it
    op.drop_column('assignments', 'keep_open')
    op.drop_column('assignments', 'automatic')
