"""Zones (polygons on the floor) and the robots' pose history (kept at a bounded rate).

Revision ID: 0007
Revises: 0004 (the lead chains it after the other branches' 0005 and 0006 at merge time)
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0007"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "zones",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String, nullable=False, unique=True),
        sa.Column("floor", sa.String, nullable=False, server_default=""),
        sa.Column("polygon", sa.JSON, nullable=False),
        sa.Column("dwell_s", sa.Float, nullable=True),
        sa.Column("created_at", sa.DateTime, nullable=False),
    )
    op.create_table(
        "pose_history",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("robot", sa.String, nullable=False),
        sa.Column("t", sa.DateTime, nullable=False),
        sa.Column("t_ns", sa.BigInteger, nullable=False),
        sa.Column("x", sa.Float, nullable=False),
        sa.Column("y", sa.Float, nullable=False),
        sa.Column("theta", sa.Float, nullable=False),
        sa.Column("sigma_m", sa.Float, nullable=True),
        sa.Column("mode", sa.String, nullable=False),
    )
    op.create_index("ix_pose_history_robot_t", "pose_history", ["robot", "t"])
    op.create_index("ix_pose_history_t", "pose_history", ["t"])


def downgrade() -> None:
    op.drop_index("ix_pose_history_t", "pose_history")
    op.drop_index("ix_pose_history_robot_t", "pose_history")
    op.drop_table("pose_history")
    op.drop_table("zones")
