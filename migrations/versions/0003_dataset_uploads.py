"""dataset uploads and raw chunks: identical re-uploads skip parsing; raw bytes in pieces

Adds ``dataset_uploads`` (hash of an upload as sent -> dataset id) and ``dataset_chunks``
(the raw bytes of a dataset in pieces of at most 1 MiB, written and read without holding a large
log whole), moves ``datasets.raw`` into chunks and drops the column. Existing datasets have no
upload hash; their next identical upload is parsed once and then recorded.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-23
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | Sequence[str] | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

ID = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
CHUNK = 1 << 20


def upgrade() -> None:
    op.create_table(
        "dataset_uploads",
        sa.Column("upload_hash", sa.String(64), nullable=False),
        sa.Column("dataset_id", ID, nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("upload_hash", name="pk_dataset_uploads"),
        sa.ForeignKeyConstraint(
            ["dataset_id"],
            ["datasets.id"],
            name="fk_dataset_uploads_dataset_id_datasets",
            ondelete="CASCADE",
        ),
    )
    op.create_index("ix_dataset_uploads_dataset_id", "dataset_uploads", ["dataset_id"])
    chunks = op.create_table(
        "dataset_chunks",
        sa.Column("dataset_id", ID, nullable=False),
        sa.Column("seq", sa.Integer(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.PrimaryKeyConstraint("dataset_id", "seq", name="pk_dataset_chunks"),
        sa.ForeignKeyConstraint(
            ["dataset_id"],
            ["datasets.id"],
            name="fk_dataset_chunks_dataset_id_datasets",
            ondelete="CASCADE",
        ),
    )
    conn = op.get_bind()
    ids = conn.execute(sa.text("SELECT id FROM datasets WHERE raw IS NOT NULL ORDER BY id"))
    for dataset_id in ids.scalars().all():
        raw = conn.execute(
            sa.text("SELECT raw FROM datasets WHERE id = :id"), {"id": dataset_id}
        ).scalar_one()
        rows = [
            {"dataset_id": dataset_id, "seq": k, "data": bytes(raw[start : start + CHUNK])}
            for k, start in enumerate(range(0, len(raw), CHUNK))
        ]
        if rows:
            conn.execute(chunks.insert(), rows)
    # a plain ALTER TABLE (SQLite >= 3.35): a batch "move and copy" would drop the table and,
    # with foreign keys on, cascade the delete to the chunks just written
    op.drop_column("datasets", "raw")


def downgrade() -> None:
    op.add_column("datasets", sa.Column("raw", sa.LargeBinary(), nullable=True))
    conn = op.get_bind()
    ids = conn.execute(sa.text("SELECT DISTINCT dataset_id FROM dataset_chunks"))
    for dataset_id in ids.scalars().all():
        parts = conn.execute(
            sa.text("SELECT data FROM dataset_chunks WHERE dataset_id = :id ORDER BY seq"),
            {"id": dataset_id},
        ).scalars()
        conn.execute(
            sa.text("UPDATE datasets SET raw = :raw WHERE id = :id"),
            {"raw": b"".join(parts), "id": dataset_id},
        )
    op.drop_table("dataset_chunks")
    op.drop_index("ix_dataset_uploads_dataset_id", table_name="dataset_uploads")
    op.drop_table("dataset_uploads")
