"""run groups: studies submitted together as repeated runs of one case

``studies.run_group``: the id of the group's first study for the K studies of one request
with ``runs`` K (seeds seed, seed + 1, ...), NULL for a study on its own. Indexed: a study's
page lists its group's runs.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-28
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0010"
down_revision: str | Sequence[str] | None = "0009"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.add_column(sa.Column("run_group", sa.BigInteger(), nullable=True))
        batch.create_index("ix_studies_run_group", ["run_group"])


def downgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.drop_index("ix_studies_run_group")
        batch.drop_column("run_group")
