"""a version per study, raised by every change of its state (HTTP ETags)

Adds ``studies.version`` (integer, 0 for existing studies; every event appended for a study and
every stage starting raises it by one), so a reader can tell that nothing changed from the
study's row alone: the API's ETags and the dashboard's polling answer 304 without reading
stages or samples.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-24
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005"
down_revision: str | Sequence[str] | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.add_column(
            sa.Column("version", sa.BigInteger(), nullable=False, server_default=sa.text("0"))
        )


def downgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.drop_column("version")
