"""Each landmark's uncertainty and its evidence: sigma_m (metres), covariance (3 x 3, m^2)
and evidence (where they come from), kept with the map across restarts.

Revision ID: 0008
Revises: 0007
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("landmarks") as batch:
        batch.add_column(sa.Column("sigma_m", sa.Float, nullable=True))
        batch.add_column(sa.Column("covariance", sa.JSON, nullable=True))
        batch.add_column(sa.Column("evidence", sa.JSON, nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("landmarks") as batch:
        batch.drop_column("evidence")
        batch.drop_column("covariance")
        batch.drop_column("sigma_m")
