"""study kinds: Morris sensitivity studies beside TMCMC calibrations

Adds ``studies.kind`` ("tmcmc" for every existing study, or "morris") with its check
constraint and index, and ``studies.result`` (the Morris statistics of a finished sensitivity
study, JSON).

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | Sequence[str] | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.add_column(sa.Column("kind", sa.String(16), nullable=False, server_default="tmcmc"))
        batch.add_column(sa.Column("result", sa.JSON(), nullable=True))
        batch.create_check_constraint("kind", "kind IN ('tmcmc', 'morris')")
        batch.create_index("ix_studies_kind_id", ["kind", "id"])


def downgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.drop_index("ix_studies_kind_id")
        batch.drop_constraint("kind", type_="check")
        batch.drop_column("result")
        batch.drop_column("kind")
