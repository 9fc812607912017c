"""submission_probes: each submission's actions on its assignments' secret probe sets (drawn on the
private tracks: league.validation.probes.secret_probe_observations), which the integrity report
compares beside the public set's. Existing submissions have none: the report lists them as not yet
probed until an instructor has them probed (POST /api/integrity/probe)

Revision ID: 0023
Revises: 0022
Create Date: 2026-11-28 09:30:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0023'
down_revision = '0022'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'submission_probes',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('submission_id', sa.Integer(), nullable=False),
        sa.Column('probe_key', sa.String(length=16), nullable=False),
        sa.Column('actions', sa.LargeBinary(), nullable=True),
        sa.Column('error', sa.Text(), nullable=True),
        sa.Column('created_at', sa.DateTime(), nullable=False),
        sa.ForeignKeyConstraint(['submission_id'], ['submissions.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('submission_id', 'probe_key'),
    )
    op.create_index(op.f('ix_submission_probes_submission_id'), 'submission_probes', ['submission_id'],
                    unique=False)


def downgrade() -> None:
    op.drop_index(op.f('ix_submission_probes_submission_id'), table_name='submission_probes')
    op.drop_table('submission_probes')
