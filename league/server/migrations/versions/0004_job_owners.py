"""jobs.owner_id: whose job it is (the fair queue serves owners in turn; in-flight limits)

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23 18:30:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0004'
down_revision = '0003'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('jobs') as batch:
        batch.add_column(sa.Column('owner_id', sa.Integer(), nullable=True))
        batch.create_foreign_key('fk_jobs_owner_id_users', 'users', ['owner_id'], ['id'])
        batch.create_index('ix_jobs_status_owner', ['status', 'owner_id'])
    op.execute("UPDATE jobs SET owner_id = (SELECT owner_id FROM submissions "
               "WHERE submissions.id = jobs.submission_id) WHERE submission_id IS NOT NULL")
    op.execute("UPDATE jobs SET owner_id = (SELECT created_by_id FROM races WHERE races.id = jobs.race_id) "
               "WHERE race_id IS NOT NULL")


def downgrade() -> None:
    with op.batch_alter_table('jobs') as batch:
        batch.drop_index('ix_jobs_status_owner')
        batch.drop_constraint('fk_jobs_owner_id_users', type_='foreignkey')
        batch.drop_column('owner_id')
