"""study kinds as plug-ins: each kind's own payload; kinds checked by the registry

Adds ``studies.payload`` (JSON, the kind's own settings, e.g. the study a posterior update
starts from) and drops the CHECK constraint on ``studies.kind``: the kinds are those of the
service's registry (``services.studies.kinds``), so adding one needs no migration. Downgrading
refuses while studies of kinds the earlier schema does not know exist (delete them first).

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: str | Sequence[str] | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

OLD_KINDS = ("tmcmc", "morris")


def upgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.add_column(sa.Column("payload", sa.JSON(), nullable=True))
        batch.drop_constraint("kind", type_="check")


def downgrade() -> None:
    studies = sa.table("studies", sa.column("id"), sa.column("kind"))
    others = (
        op.get_bind()
        .execute(sa.select(studies.c.id, studies.c.kind).where(studies.c.kind.notin_(OLD_KINDS)))
        .all()
    )
    if others:
        listed = ", ".join(f"{i} ({k})" for i, k in others[:10])
        raise RuntimeError(
            f"cannot downgrade below 0004: {len(others)} studies are of kinds revision 0003 "
            f"does not know ({listed}); delete them first"
        )
    with op.batch_alter_table("studies") as batch:
        batch.create_check_constraint("kind", "kind IN ('tmcmc', 'morris')")
        batch.drop_column("payload")
