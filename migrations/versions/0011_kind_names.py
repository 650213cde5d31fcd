"""one name per kind: "tmcmc" becomes "calibration", "morris" becomes "sensitivity"

The kinds are named as the user meets them everywhere else (``scm-calib calibrate``, the
``/sensitivity`` route, ``scm-calib sensitivity``): stored studies of the old names are renamed
and ``studies.kind``'s server default (the kind of rows from before studies had kinds) follows.
The downgrade gives the old names back.

Revision ID: 0011
Revises: 0010
Create Date: 2026-12-07
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0011"
down_revision: str | Sequence[str] | None = "0010"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: old name -> new name
RENAMED = {"tmcmc": "calibration", "morris": "sensitivity"}


def _rename(names: dict[str, str], default: str) -> None:
    studies = sa.table("studies", sa.column("kind", sa.String(16)))
    for old, new in names.items():
        op.execute(studies.update().where(studies.c.kind == old).values(kind=new))
    with op.batch_alter_table("studies") as batch:
        batch.alter_column(
            "kind", existing_type=sa.String(16), existing_nullable=False, server_default=default
        )


def upgrade() -> None:
    _rename(RENAMED, "calibration")


def downgrade() -> None:
    _rename({new: old for old, new in RENAMED.items()}, "tmcmc")
