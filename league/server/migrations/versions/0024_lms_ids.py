"""users.canvas_id and users.sis_login_id: the Canvas user ID and SIS Login ID of a roster imported
from Canvas's gradebook export, echoed by the Canvas grade file so that Canvas matches each student
by its own ids rather than by name. Existing users keep both empty (importing Canvas's export again
fills them in)

Revision ID: 0024
Revises: 0023
Create Date: 2026-11-28 09:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0024'
down_revision = '0023'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('users', sa.Column('canvas_id', sa.String(length=64), nullable=True))
    op.add_column('users', sa.Column('sis_login_id', sa.String(length=254), nullable=True))


def downgrade() -> None:
    # in place (SQLite >= 3.35), as 0008: a batch copy of users is refused by the foreign keys to it
    op.drop_column('users', 'sis_login_id')
    op.drop_column('users', 'canvas_id')
