"""assignments: a course has several (tracks, upload window, late window, quota, private test seed),
student_assignments (extension, selection, the final frozen at the student's close time); every
submission belongs to one (submissions.assignment_id) and may be late; evaluations name the
assignment whose settings they ran and their track (public or private)

Each course becomes one default assignment with its evaluation settings (the courses' columns move
there), open since ever, no due time, and a private seed drawn now: every submission and evaluation
belongs to it (the baselines' to the first course's), so every board ranks what it ranked.

Revision ID: 0010
Revises: 0012
Create Date: 2026-11-25 19:00:00
"""
import secrets

import sqlalchemy as sa
from alembic import op


revision = '0010'
down_revision = '0012'  # re-chained onto main's head at the merge (0008 -> 0015 -> 0013 -> 0012)
branch_labels = None
depends_on = None

DEFAULT_ASSIGNMENT = "default"


def upgrade() -> None:
    op.create_table(
        'assignments',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('course_id', sa.Integer(), nullable=False),
        sa.Column('name', sa.String(length=100), nullable=False),
        sa.Column('description', sa.Text(), nullable=False),
        sa.Column('seed', sa.BigInteger(), nullable=False),
        sa.Column('episodes', sa.Integer(), nullable=False),
        sa.Column('env_options', sa.JSON(), nullable=False),
        sa.Column('private_seed', sa.BigInteger(), nullable=False),
        sa.Column('opens_at', sa.DateTime(), nullable=True),
        sa.Column('due_at', sa.DateTime(), nullable=True),
        sa.Column('late_until', sa.DateTime(), nullable=True),
        sa.Column('late_penalty', sa.Float(), nullable=True),
        sa.Column('daily_quota', sa.Integer(), nullable=True),
        sa.Column('auto_publish', sa.Boolean(), nullable=False),
        sa.Column('published_at', sa.DateTime(), nullable=True),
        sa.Column('created_at', sa.DateTime(), nullable=False),
        sa.Column('updated_at', sa.DateTime(), nullable=False),
        sa.ForeignKeyConstraint(['course_id'], ['courses.id'], ),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('course_id', 'name'),
    )
    op.create_index('ix_assignments_course_id', 'assignments', ['course_id'])
    # plain ALTER TABLE (no batch copy on SQLite: the foreign keys to these tables forbid it), as 0007
    add_reference('submissions', 'assignment_id', 'assignments')
    op.add_column('submissions', sa.Column('late', sa.Boolean(), server_default=sa.text('false'), nullable=False))
    op.create_index('ix_submissions_assignment_id', 'submissions', ['assignment_id'])
    add_reference('evaluations', 'assignment_id', 'assignments')
    op.add_column('evaluations', sa.Column('track', sa.String(length=10), server_default='public', nullable=False))
    op.create_table(
        'student_assignments',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('assignment_id', sa.Integer(), nullable=False),
        sa.Column('user_id', sa.Integer(), nullable=False),
        sa.Column('extension_due_at', sa.DateTime(), nullable=True),
        sa.Column('selected_submission_id', sa.Integer(), nullable=True),
        sa.Column('final_at', sa.DateTime(), nullable=True),
        sa.Column('final_submission_id', sa.Integer(), nullable=True),
        sa.Column('final_evaluation_id', sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(['assignment_id'], ['assignments.id'], ),
        sa.ForeignKeyConstraint(['user_id'], ['users.id'], ),
        sa.ForeignKeyConstraint(['selected_submission_id'], ['submissions.id'], ),
        sa.ForeignKeyConstraint(['final_submission_id'], ['submissions.id'], ),
        sa.ForeignKeyConstraint(['final_evaluation_id'], ['evaluations.id'], ),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('assignment_id', 'user_id'),
    )
    op.create_index('ix_student_assignments_user_id', 'student_assignments', ['user_id'])
    default_assignments(op.get_bind())
    for column in ('eval_seed', 'eval_episodes', 'eval_env_options'):
        op.drop_column('courses', column)  # SQLite >= 3.35 drops a column in place


def add_reference(table: str, column: str, target: str) -> None:
    """A nullable foreign key column, added in place (SQLite takes REFERENCES in ADD COLUMN, not a constraint)."""
    if op.get_bind().dialect.name == 'sqlite':
        op.execute(f'ALTER TABLE {table} ADD COLUMN {column} INTEGER REFERENCES {target} (id)')
    else:
        op.add_column(table, sa.Column(column, sa.Integer(), sa.ForeignKey(f'{target}.id'), nullable=True))


def default_assignments(connection) -> None:
    """One default assignment per course with its settings; every submission and evaluation in it."""
    courses = sa.table('courses', sa.column('id', sa.Integer), sa.column('eval_seed', sa.BigInteger),
                       sa.column('eval_episodes', sa.Integer), sa.column('eval_env_options', sa.JSON),
                       sa.column('created_at', sa.DateTime))
    assignments = sa.table('assignments', *(sa.column(name) for name in (
        'id', 'course_id', 'name', 'description', 'seed', 'episodes', 'private_seed', 'auto_publish', 'created_at',
        'updated_at')), sa.column('env_options', sa.JSON))
    users = sa.table('users', sa.column('id', sa.Integer), sa.column('course_id', sa.Integer))
    submissions = sa.table('submissions', sa.column('owner_id', sa.Integer), sa.column('assignment_id', sa.Integer),
                           sa.column('id', sa.Integer))
    evaluations = sa.table('evaluations', sa.column('submission_id', sa.Integer),
                           sa.column('assignment_id', sa.Integer))
    first = None
    for course_id, seed, episodes, options, created_at in connection.execute(
            sa.select(courses.c.id, courses.c.eval_seed, courses.c.eval_episodes, courses.c.eval_env_options,
                      courses.c.created_at).order_by(courses.c.id)):
        assignment_id = connection.execute(assignments.insert().values(
            course_id=course_id, name=DEFAULT_ASSIGNMENT, description="", seed=seed, episodes=episodes,
            env_options=options or {}, private_seed=secrets.randbits(32), auto_publish=False,
            created_at=created_at, updated_at=created_at).returning(assignments.c.id)).scalar_one()
        first = assignment_id if first is None else first
        members = sa.select(users.c.id).where(users.c.course_id == course_id)
        connection.execute(submissions.update().where(submissions.c.owner_id.in_(members))
                           .values(assignment_id=assignment_id))
    if first is not None:  # the baselines' account has no course: they were evaluated with the first's
        connection.execute(submissions.update().where(submissions.c.assignment_id.is_(None))
                           .values(assignment_id=first))
    connection.execute(evaluations.update().values(assignment_id=sa.select(submissions.c.assignment_id).where(
        submissions.c.id == evaluations.c.submission_id).scalar_subquery()))


def downgrade() -> None:
    op.add_column('courses', sa.Column('eval_seed', sa.BigInteger(), server_default='0', nullable=False))
    op.add_column('courses', sa.Column('eval_episodes', sa.Integer(), server_default='100', nullable=False))
    op.add_column('courses', sa.Column('eval_env_options', sa.JSON(), server_default='{}', nullable=False))
    connection = op.get_bind()
    courses = sa.table('courses', sa.column('id', sa.Integer), sa.column('eval_seed', sa.BigInteger),
                       sa.column('eval_episodes', sa.Integer), sa.column('eval_env_options', sa.JSON))
    assignments = sa.table('assignments', sa.column('id', sa.Integer), sa.column('course_id', sa.Integer),
                           sa.column('seed', sa.BigInteger), sa.column('episodes', sa.Integer),
                           sa.column('env_options', sa.JSON))
    defaults = sa.select(sa.func.min(assignments.c.id)).group_by(assignments.c.course_id)
    for course_id, seed, episodes, options in connection.execute(
            sa.select(assignments.c.course_id, assignments.c.seed, assignments.c.episodes,
                      assignments.c.env_options).where(assignments.c.id.in_(defaults))):
        connection.execute(courses.update().where(courses.c.id == course_id)
                           .values(eval_seed=seed, eval_episodes=episodes, eval_env_options=options))
    op.drop_index('ix_student_assignments_user_id', 'student_assignments')
    op.drop_table('student_assignments')
    op.drop_column('evaluations', 'track')
    op.drop_column('evaluations', 'assignment_id')
    op.drop_index('ix_submissions_assignment_id', 'submissions')
    op.drop_column('submissions', 'late')
    op.drop_column('submissions', 'assignment_id')
    op.drop_index('ix_assignments_course_id', 'assignments')
    op.drop_table('assignments')
