"""ix_jobs_queued_kind, ix_jobs_queued_other: the queued jobs in the order of their ids, per priority and
kind, and per priority for the kinds other than validations and evaluations (partial indexes of the
queued rows); ix_jobs_status_owner_turn (status, owner, priority, id) replaces ix_jobs_status_owner
(status, owner). A claim reads the first queued jobs that take their owner's first turn from the
former, validations, then evaluations, then the rest, each checked against its owner's running and
earlier jobs by the latter, no longer ranking every queued and running job: with 10,000 queued,
that cost PostgreSQL 26.5 ms of CPU per claim (benchmarks/bench_claims.py).

Revision ID: 0026
Revises: 0025
Create Date: 2026-11-28 12:30:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0026'
down_revision = '0025'
branch_labels = None
depends_on = None

QUEUED = sa.text("status = 'queued'")
QUEUED_OTHER_KIND = sa.text("status = 'queued' AND kind NOT IN ('validate', 'evaluate')")


def upgrade() -> None:
    op.create_index('ix_jobs_status_owner_turn', 'jobs', ['status', 'owner_id', 'priority', 'id'])
    op.drop_index('ix_jobs_status_owner', 'jobs')
    op.create_index('ix_jobs_queued_kind', 'jobs', ['priority', 'kind', 'id'], postgresql_where=QUEUED,
                    sqlite_where=QUEUED)
    op.create_index('ix_jobs_queued_other', 'jobs', ['priority', 'id'], postgresql_where=QUEUED_OTHER_KIND,
                    sqlite_where=QUEUED_OTHER_KIND)


def downgrade() -> None:
    op.drop_index('ix_jobs_queued_other', 'jobs')
    op.drop_index('ix_jobs_queued_kind', 'jobs')
    op.create_index('ix_jobs_status_owner', 'jobs', ['status', 'owner_id'])
    op.drop_index('ix_jobs_status_owner_turn', 'jobs')
