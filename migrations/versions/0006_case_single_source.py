"""the case document is the single source of a study

Drops ``studies.priors``, ``studies.sampler`` and ``studies.simulator``: they were copies of
what the case document (``case_spec``) says, made when the study was stored, and a screening
used them with other meanings (its factor box and design settings). The study's kind now
derives them from the case when the study is read. A screening's design settings (r, levels,
joint k*, every factor's resolved bounds), which the case does not hold, move into its own
``payload`` as ``{"design": ...}``.

The downgrade puts the columns back, filled from the case and the payload with the same
derivations the kinds use (``scm_core.calibration``); a case that is not a valid case document
(none is stored by the service) gets empty documents.

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-24
"""

from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from alembic import op

revision: str = "0006"
down_revision: str | Sequence[str] | None = "0005"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

COLUMNS = ("priors", "sampler", "simulator")


def _studies(*columns: str) -> sa.TableClause:
    return sa.table(
        "studies",
        sa.column("id"),
        sa.column("kind"),
        sa.column("seed"),
        sa.column("case_spec", sa.JSON()),
        sa.column("payload", sa.JSON()),
        *(sa.column(c, sa.JSON()) for c in columns),
    )


def upgrade() -> None:
    bind = op.get_bind()
    studies = _studies("sampler")
    rows = bind.execute(
        sa.select(studies.c.id, studies.c.payload, studies.c.sampler).where(
            studies.c.kind == "morris"
        )
    ).all()
    for study_id, payload, sampler in rows:
        bind.execute(
            studies.update()
            .where(studies.c.id == study_id)
            .values(payload={**(payload or {}), "design": sampler})
        )
    with op.batch_alter_table("studies") as batch:
        for column in COLUMNS:
            batch.drop_column(column)


def _derived(kind: str, seed: int, case: dict[str, Any], payload: dict[str, Any] | None):
    """(priors, sampler, simulator) as revision 0005 stored them."""
    from scm_core.calibration import CaseDefinition, MorrisSettings, sensitivity_design

    try:
        definition = CaseDefinition.from_dict(case)
    except ValueError:
        return {}, {}, {}
    simulator = dict(definition.simulator)
    if kind == "morris":
        design = dict((payload or {}).get("design") or {})
        bounds = {k: (float(v[0]), float(v[1])) for k, v in design.get("bounds", {}).items()}
        morris = MorrisSettings(
            int(design["r"]), int(design["levels"]), int(seed), bool(design["joint_k"]), bounds
        )
        built = sensitivity_design(definition, morris)
        return built.factor_box(), design, simulator
    return definition.prior().to_dict(), definition.tmcmc_settings().to_dict(), simulator


def downgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        for column in COLUMNS:
            batch.add_column(sa.Column(column, sa.JSON(), nullable=True))
    bind = op.get_bind()
    studies = _studies(*COLUMNS)
    rows = bind.execute(
        sa.select(
            studies.c.id, studies.c.kind, studies.c.seed, studies.c.case_spec, studies.c.payload
        )
    ).all()
    for study_id, kind, seed, case, payload in rows:
        priors, sampler, simulator = _derived(kind, seed, case, payload)
        if kind == "morris" and payload is not None:
            payload = {k: v for k, v in payload.items() if k != "design"} or None
        bind.execute(
            studies.update()
            .where(studies.c.id == study_id)
            .values(priors=priors, sampler=sampler, simulator=simulator, payload=payload)
        )
    with op.batch_alter_table("studies") as batch:
        for column in COLUMNS:
            batch.alter_column(column, existing_type=sa.JSON(), nullable=False)
