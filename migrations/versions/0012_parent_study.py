"""parent studies: the study a new one starts from, as a column

``studies.parent_id``: the study whose results a study starts from (an update's earlier
calibration, a prediction's posterior), NULL for a study that starts from none. Until now only
the kind's payload held it (``update_of``, ``study_id``), which the store keeps as a document and
does not query inside; the column is indexed, so that a study's page finds the studies made
from it with one query. Existing rows are filled from their payloads. No foreign key: a
study's row outlives nothing it names (studies are not deleted), and the payload stays the
kind's record.

Revision ID: 0012
Revises: 0011
Create Date: 2026-12-07
"""

import json
from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0012"
down_revision: str | Sequence[str] | None = "0011"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: kind -> the payload key naming the study it starts from (the kinds as of 0011)
PARENT_KEYS = {"update": "update_of", "prediction": "study_id"}


def _parent(payload: object, key: str) -> int | None:
    """The parent id a stored payload (a JSON document, or its text) names under ``key``."""
    doc = json.loads(payload) if isinstance(payload, str) else payload
    value = doc.get(key) if isinstance(doc, dict) else None
    return int(value) if isinstance(value, int) and not isinstance(value, bool) else None


def upgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.add_column(sa.Column("parent_id", sa.BigInteger(), nullable=True))
        batch.create_index("ix_studies_parent_id", ["parent_id"])
    studies = sa.table(
        "studies",
        sa.column("id", sa.BigInteger()),
        sa.column("kind", sa.String(16)),
        sa.column("payload", sa.JSON()),
        sa.column("parent_id", sa.BigInteger()),
    )
    conn = op.get_bind()
    rows = conn.execute(
        sa.select(studies.c.id, studies.c.kind, studies.c.payload).where(
            studies.c.kind.in_(list(PARENT_KEYS))
        )
    ).all()
    for study_id, kind, payload in rows:
        parent = _parent(payload, PARENT_KEYS[kind])
        if parent is not None:
            conn.execute(studies.update().where(studies.c.id == study_id).values(parent_id=parent))


def downgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.drop_index("ix_studies_parent_id")
        batch.drop_column("parent_id")
