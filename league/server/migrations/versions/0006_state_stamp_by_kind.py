"""the public answers' state stamp reads the newest finished evaluation and heat, each from one
index of (kind, finished_at), no longer every finished job and every submission change: in a
deadline rush four in five of those were uploads and validations, which change no public answer,
yet made the next request recompute the leaderboard

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-25 10:00:00
"""
from alembic import op


revision = '0006'
down_revision = '0005'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_index('ix_jobs_kind_finished', 'jobs', ['kind', 'finished_at'])
    op.drop_index('ix_jobs_finished_at', 'jobs')
    op.drop_index('ix_submissions_updated_at', 'submissions')


def downgrade() -> None:
    op.create_index('ix_submissions_updated_at', 'submissions', ['updated_at'])
    op.create_index('ix_jobs_finished_at', 'jobs', ['finished_at'])
    op.drop_index('ix_jobs_kind_finished', 'jobs')
