"""A robot's serial wheel-speed port and baud rate.

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("robots") as batch:
        batch.add_column(sa.Column("wheel_port", sa.String, nullable=True))
        batch.add_column(
            sa.Column("wheel_baud", sa.Integer, nullable=False, server_default="115200")
        )


def downgrade() -> None:
    with op.batch_alter_table("robots") as batch:
        batch.drop_column("wheel_baud")
        batch.drop_column("wheel_port")
