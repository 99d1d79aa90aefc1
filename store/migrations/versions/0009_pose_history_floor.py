"""The floor of each kept pose (a two-floor site's history played back per floor); poses
kept before it are on floor "0" (a site kept history on one floor before floors existed).

Revision ID: 0009
Revises: 0008
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0009"
down_revision = "0008"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("pose_history") as batch:
        batch.add_column(sa.Column("floor", sa.String, nullable=False, server_default="0"))


def downgrade() -> None:
    with op.batch_alter_table("pose_history") as batch:
        batch.drop_column("floor")
