"""stored cases name their population-jump share

From this revision a case that leaves ``surrogate_jumps`` out takes its move scheme's default
(population jumps in the accelerated "waste-free" form, none in "resample-move" and "leader").
Cases stored before meant no jumps (0.0) whatever their moves. Cases written since the key
existed name it already; this revision writes 0.0 into every stored case that lacks it, so
every study keeps the sampler it was created with. The downgrade leaves the explicit value in
place: the old code reads it as it is.

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-27
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0008"
down_revision: str | Sequence[str] | None = "0007"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: what a stored case's missing ``surrogate_jumps`` meant before this revision
OLD_JUMPS = 0.0


def upgrade() -> None:
    bind = op.get_bind()
    studies = sa.table("studies", sa.column("id"), sa.column("case_spec", sa.JSON()))
    for study_id, case in bind.execute(sa.select(studies.c.id, studies.c.case_spec)).all():
        if not isinstance(case, dict):
            continue
        sampler = dict(case.get("sampler") or {})
        if sampler.get("surrogate_jumps") is not None:
            continue
        bind.execute(
            studies.update()
            .where(studies.c.id == study_id)
            .values(case_spec={**case, "sampler": {**sampler, "surrogate_jumps": OLD_JUMPS}})
        )


def downgrade() -> None:
    """Nothing to undo: the explicit value means what it meant before."""
