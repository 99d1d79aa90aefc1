"""The first schema: landmarks, robots, battery readings, events, audit log, API keys.

Revision ID: 0001
Revises:
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "landmarks",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=False),
        sa.Column("x", sa.Float, nullable=False),
        sa.Column("y", sa.Float, nullable=False),
        sa.Column("z", sa.Float, nullable=False),
        sa.Column("radio", sa.String, nullable=True),
        sa.Column("locked", sa.Boolean, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.Column("updated_at", sa.DateTime, nullable=False),
    )
    op.create_index("ix_landmarks_radio", "landmarks", ["radio"], unique=True)
    op.create_table(
        "robots",
        sa.Column("name", sa.String(64), primary_key=True),
        sa.Column("source", sa.String, nullable=False),
        sa.Column("device", sa.String, nullable=True),
        sa.Column("wheel_base", sa.Float, nullable=False),
        sa.Column("max_speed", sa.Float, nullable=False),
        sa.Column("camera", sa.JSON, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.Column("updated_at", sa.DateTime, nullable=False),
    )
    op.create_table(
        "battery_readings",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("landmark_id", sa.Integer, sa.ForeignKey("landmarks.id", ondelete="CASCADE")),
        sa.Column("t", sa.DateTime, nullable=False),
        sa.Column("supply_mv", sa.Integer, nullable=False),
    )
    op.create_index("ix_battery_readings_landmark_id", "battery_readings", ["landmark_id"])
    op.create_index("ix_battery_readings_t", "battery_readings", ["t"])
    op.create_table(
        "events",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("t", sa.DateTime, nullable=False),
        sa.Column("kind", sa.String, nullable=False),
        sa.Column("robot", sa.String, nullable=True),
        sa.Column("landmark_id", sa.Integer, nullable=True),
        sa.Column("message", sa.String, nullable=False),
        sa.Column("data", sa.JSON, nullable=False),
    )
    op.create_index("ix_events_t", "events", ["t"])
    op.create_index("ix_events_kind", "events", ["kind"])
    op.create_table(
        "audit_log",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("t", sa.DateTime, nullable=False),
        sa.Column("actor", sa.String, nullable=False),
        sa.Column("action", sa.String, nullable=False),
        sa.Column("landmark_id", sa.Integer, nullable=True),
        sa.Column("before", sa.JSON, nullable=True),
        sa.Column("after", sa.JSON, nullable=True),
    )
    op.create_index("ix_audit_log_t", "audit_log", ["t"])
    op.create_index("ix_audit_log_landmark_id", "audit_log", ["landmark_id"])
    op.create_table(
        "api_keys",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String, nullable=False),
        sa.Column("role", sa.String, nullable=False),
        sa.Column("prefix", sa.String, nullable=False),
        sa.Column("hash", sa.String, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.Column("revoked", sa.Boolean, nullable=False),
    )
    op.create_index("ix_api_keys_hash", "api_keys", ["hash"], unique=True)


def downgrade() -> None:
    for table in ("api_keys", "audit_log", "events", "battery_readings", "robots", "landmarks"):
        op.drop_table(table)
