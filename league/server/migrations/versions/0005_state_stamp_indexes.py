"""indexes of the public answers' state stamp (league/server/api/cache.py): the newest finished job,
the newest submission change, the newest revocation, each read from its index

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-23 20:00:00
"""
from alembic import op


revision = '0005'
down_revision = '0004'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_index('ix_jobs_finished_at', 'jobs', ['finished_at'])
    op.create_index('ix_submissions_updated_at', 'submissions', ['updated_at'])
    op.create_index('ix_users_revoked_at', 'users', ['revoked_at'])


def downgrade() -> None:
    op.drop_index('ix_users_revoked_at', 'users')
    op.drop_index('ix_submissions_updated_at', 'submissions')
    op.drop_index('ix_jobs_finished_at', 'jobs')
