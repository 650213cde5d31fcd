"""stored cases name their sampler form explicitly

From this revision a case that leaves ``moves``, ``delayed_acceptance``, ``surrogate_steps``,
``proposal_scale`` or ``resampling`` out takes its move scheme's defaults (the accelerated
accurate form for "waste-free", plain steps for "resample-move" and "leader"). Cases stored
before left some of these keys out and meant the old defaults (resample-move, no surrogate,
one inner step, linear walk, systematic resampling; the case document omitted ``resampling``
when it was systematic). This revision writes those values into every stored case that lacks
them, so every study keeps the sampler it was created with. The downgrade leaves the explicit
values in place: the old code reads them as they are.

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-27
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0007"
down_revision: str | Sequence[str] | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: what a stored case's missing sampler keys meant before this revision
OLD_DEFAULTS = {
    "moves": "resample-move",
    "delayed_acceptance": False,
    "surrogate_steps": 1,
    "proposal_scale": "linear",
    "resampling": "systematic",
}


def upgrade() -> None:
    bind = op.get_bind()
    studies = sa.table("studies", sa.column("id"), sa.column("case_spec", sa.JSON()))
    for study_id, case in bind.execute(sa.select(studies.c.id, studies.c.case_spec)).all():
        if not isinstance(case, dict):
            continue
        sampler = dict(case.get("sampler") or {})
        missing = {k: v for k, v in OLD_DEFAULTS.items() if sampler.get(k) is None}
        if not missing:
            continue
        bind.execute(
            studies.update()
            .where(studies.c.id == study_id)
            .values(case_spec={**case, "sampler": {**sampler, **missing}})
        )


def downgrade() -> None:
    """Nothing to undo: the explicit values mean what they meant before."""
