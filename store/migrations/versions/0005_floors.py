"""Floors: a site has floors, every landmark hangs on one, each floor's map has versions.

A database of a single-floor site keeps its map: the migration creates floor "0" (level 0,
height 0 m) and puts every landmark on it. The map versions table starts empty; the server
records each floor's first version when it opens the database (`MapVersions.sync`).

Revision ID: 0005
Revises: 0004
"""

from __future__ import annotations

from datetime import UTC, datetime

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    floors = op.create_table(
        "floors",
        sa.Column("id", sa.String(32), primary_key=True),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("level", sa.Integer, nullable=False),
        sa.Column("height", sa.Float, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
    )
    now = datetime.now(UTC).replace(tzinfo=None)
    op.bulk_insert(
        floors, [{"id": "0", "name": "Floor 0", "level": 0, "height": 0.0, "created_at": now}]
    )
    # a plain ADD COLUMN: rebuilding `landmarks` (as a batch with a new foreign key does on
    # SQLite) would cascade-delete every battery reading. SQLite cannot add the foreign key
    # to an existing table, so there the data layer alone checks the floor (it does on
    # every write: `store.floors.check_floors`).
    op.add_column(
        "landmarks", sa.Column("floor", sa.String(32), nullable=False, server_default="0")
    )
    op.create_index("ix_landmarks_floor", "landmarks", ["floor"])
    if op.get_bind().dialect.name != "sqlite":
        op.create_foreign_key("fk_landmarks_floor", "landmarks", "floors", ["floor"], ["id"])
    op.create_table(
        "map_versions",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("floor", sa.String, sa.ForeignKey("floors.id", ondelete="CASCADE")),
        sa.Column("version", sa.Integer, nullable=False),
        sa.Column("hash", sa.String, nullable=False),
        sa.Column("t", sa.DateTime, nullable=False),
        sa.Column("actor", sa.String, nullable=False),
        sa.Column("action", sa.String, nullable=False),
        sa.Column("audit_id", sa.Integer, nullable=True),
        sa.Column("landmarks", sa.JSON, nullable=False),
        sa.UniqueConstraint("floor", "version"),
    )
    op.create_index("ix_map_versions_floor", "map_versions", ["floor"])


def downgrade() -> None:
    op.drop_table("map_versions")
    op.drop_index("ix_landmarks_floor", "landmarks")
    if op.get_bind().dialect.name != "sqlite":
        op.drop_constraint("fk_landmarks_floor", "landmarks", type_="foreignkey")
    op.drop_column("landmarks", "floor")  # SQLite >= 3.35: in place, readings kept
    op.drop_table("floors")
