"""audit_events: who revoked, cancelled, re-ran, changed settings, created or deleted what
(league.server.course.audit); a new table, so existing rows are untouched

Revision ID: 0015
Revises: 0008
Create Date: 2026-11-25 19:10:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0015'
down_revision = '0008'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'audit_events',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('at', sa.DateTime(), nullable=False),
        sa.Column('course_id', sa.Integer(), nullable=True),
        sa.Column('actor_id', sa.Integer(), nullable=True),
        sa.Column('actor_name', sa.String(length=100), nullable=False),
        sa.Column('action', sa.String(length=40), nullable=False),
        sa.Column('target_kind', sa.String(length=20), nullable=False),
        sa.Column('target_id', sa.BigInteger(), nullable=True),
        sa.Column('details', sa.JSON(), nullable=False),
        sa.PrimaryKeyConstraint('id'),
    )
    op.create_index('ix_audit_events_at', 'audit_events', ['at'])
    op.create_index('ix_audit_events_course_id', 'audit_events', ['course_id'])


def downgrade() -> None:
    op.drop_index('ix_audit_events_course_id', 'audit_events')
    op.drop_index('ix_audit_events_at', 'audit_events')
    op.drop_table('audit_events')
