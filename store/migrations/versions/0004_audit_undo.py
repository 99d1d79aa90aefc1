"""Undo and redo per author: the audit record an undo/redo acts on, and each edit's state.

Revision ID: 0004
Revises: 0003
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("audit_log") as batch:
        batch.add_column(sa.Column("target_id", sa.Integer, nullable=True))
        batch.add_column(sa.Column("undo_state", sa.String, nullable=False, server_default=""))
    # before 0004 an undone edit was renamed "<action>-undone"; it can no longer be redone
    for action in ("create", "update", "delete", "import"):
        op.execute(
            sa.text(
                "UPDATE audit_log SET action = :a, undo_state = 'dropped' WHERE action = :old"
            ).bindparams(a=action, old=f"{action}-undone")
        )


def downgrade() -> None:
    with op.batch_alter_table("audit_log") as batch:
        batch.drop_column("undo_state")
        batch.drop_column("target_id")
