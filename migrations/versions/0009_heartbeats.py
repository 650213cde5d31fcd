"""heartbeats; work batches count their model runs

Heartbeats: a row each server commits to prove the database takes writes.

``GET /health/ready`` commits a real write (the row ``ready``: when it last succeeded and how
many times) instead of rolling back an update: a database that fails at commit time (a SQLite
file made read-only, a full disk, a PostgreSQL replica or a read-only session) is then not
reported ready.

Work batches: ``model_runs``, the model runs a batch's result holds (NULL for batches stored
before, and for kinds whose planned runs are exact): a study's progress counts the runs of the
stage's done batches exactly, so it no longer drops when the stage is reduced (the reduced
stage's runs are the sum of its batches').

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-28
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0009"
down_revision: str | Sequence[str] | None = "0008"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "heartbeats",
        sa.Column("name", sa.String(length=64), nullable=False),
        sa.Column("beat_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("beats", sa.BigInteger(), nullable=False),
        sa.PrimaryKeyConstraint("name", name=op.f("pk_heartbeats")),
    )
    with op.batch_alter_table("work_batches") as batch:
        batch.add_column(sa.Column("model_runs", sa.BigInteger(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("work_batches") as batch:
        batch.drop_column("model_runs")
    op.drop_table("heartbeats")
