"""initial schema: datasets, studies, stages, work batches, samples, events

Revision ID: 0001
Revises:
Create Date: 2025-01-01

Written out explicitly with plain SQLAlchemy types (no imports from the models).
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0001"
down_revision: str | Sequence[str] | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

ID = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
JSON = sa.JSON()
TS = sa.DateTime(timezone=True)


def _in(column: str, values: tuple[str, ...]) -> str:
    return f"{column} IN ({', '.join(repr(v) for v in values)})"


def upgrade() -> None:
    op.create_table(
        "datasets",
        sa.Column("id", ID, nullable=False),
        sa.Column("content_hash", sa.String(64), nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("source_kind", sa.String(16), nullable=False),
        sa.Column("filename", sa.String(255), nullable=True),
        sa.Column("media_type", sa.String(100), nullable=True),
        sa.Column("size_bytes", sa.BigInteger(), nullable=False),
        sa.Column("raw", sa.LargeBinary(), nullable=True),
        sa.Column("meta", JSON, nullable=False),
        sa.Column("processed", JSON, nullable=False),
        sa.Column("created_at", TS, nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_datasets"),
        sa.UniqueConstraint("content_hash", name="uq_datasets_content_hash"),
        sa.CheckConstraint(
            _in("source_kind", ("timeseries", "summary")), name="ck_datasets_source_kind"
        ),
    )

    op.create_table(
        "studies",
        sa.Column("id", ID, nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("case_spec", JSON, nullable=False),
        sa.Column("priors", JSON, nullable=False),
        sa.Column("sampler", JSON, nullable=False),
        sa.Column("simulator", JSON, nullable=False),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("n_samples", sa.Integer(), nullable=False),
        sa.Column("batch_size", sa.Integer(), nullable=True),
        sa.Column("current_stage", sa.Integer(), nullable=True),
        sa.Column("log_evidence", sa.Double(), nullable=True),
        sa.Column("log_evidence_var", sa.Double(), nullable=True),
        sa.Column("model_runs", sa.BigInteger(), nullable=False),
        sa.Column("failed_runs", sa.BigInteger(), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("created_at", TS, nullable=False),
        sa.Column("updated_at", TS, nullable=False),
        sa.Column("started_at", TS, nullable=True),
        sa.Column("finished_at", TS, nullable=True),
        sa.PrimaryKeyConstraint("id", name="pk_studies"),
        sa.CheckConstraint(
            _in(
                "status",
                ("queued", "running", "completed", "failed", "cancelled", "stalled"),
            ),
            name="ck_studies_status",
        ),
    )
    op.create_index("ix_studies_status_id", "studies", ["status", "id"])

    op.create_table(
        "study_datasets",
        sa.Column("study_id", ID, nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("dataset_id", ID, nullable=False),
        sa.PrimaryKeyConstraint("study_id", "position", name="pk_study_datasets"),
        sa.UniqueConstraint("study_id", "dataset_id", name="uq_study_datasets_study_id_dataset_id"),
        sa.ForeignKeyConstraint(
            ["study_id"],
            ["studies.id"],
            name="fk_study_datasets_study_id_studies",
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["dataset_id"],
            ["datasets.id"],
            name="fk_study_datasets_dataset_id_datasets",
            ondelete="RESTRICT",
        ),
    )
    op.create_index("ix_study_datasets_dataset_id", "study_datasets", ["dataset_id"])

    op.create_table(
        "stages",
        sa.Column("id", ID, nullable=False),
        sa.Column("study_id", ID, nullable=False),
        sa.Column("stage_index", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("exponent", sa.Double(), nullable=True),
        sa.Column("prev_exponent", sa.Double(), nullable=True),
        sa.Column("beta", sa.Double(), nullable=True),
        sa.Column("acceptance", sa.Double(), nullable=True),
        sa.Column("ess", sa.Double(), nullable=True),
        sa.Column("log_evidence_increment", sa.Double(), nullable=True),
        sa.Column("log_evidence", sa.Double(), nullable=True),
        sa.Column("n_chains", sa.Integer(), nullable=False),
        sa.Column("n_steps", sa.Integer(), nullable=True),
        sa.Column("n_batches", sa.Integer(), nullable=False),
        sa.Column("model_runs", sa.BigInteger(), nullable=True),
        sa.Column("failed_runs", sa.BigInteger(), nullable=True),
        sa.Column("plan", sa.LargeBinary(), nullable=True),
        sa.Column("state_meta", JSON, nullable=True),
        sa.Column("created_at", TS, nullable=False),
        sa.Column("updated_at", TS, nullable=False),
        sa.Column("finished_at", TS, nullable=True),
        sa.PrimaryKeyConstraint("id", name="pk_stages"),
        sa.UniqueConstraint("study_id", "stage_index", name="uq_stages_study_id_stage_index"),
        sa.ForeignKeyConstraint(
            ["study_id"], ["studies.id"], name="fk_stages_study_id_studies", ondelete="CASCADE"
        ),
        sa.CheckConstraint(
            _in("status", ("planned", "running", "reducing", "done")), name="ck_stages_status"
        ),
    )

    op.create_table(
        "work_batches",
        sa.Column("id", ID, nullable=False),
        sa.Column("study_id", ID, nullable=False),
        sa.Column("stage_index", sa.Integer(), nullable=False),
        sa.Column("batch_index", sa.Integer(), nullable=False),
        sa.Column("chain_start", sa.Integer(), nullable=False),
        sa.Column("chain_stop", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.Column("worker_id", sa.String(200), nullable=True),
        sa.Column("leased_at", TS, nullable=True),
        sa.Column("lease_expires_at", TS, nullable=True),
        sa.Column("heartbeat_at", TS, nullable=True),
        sa.Column("dispatched_at", TS, nullable=True),
        sa.Column("finished_at", TS, nullable=True),
        sa.Column("result", sa.LargeBinary(), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("created_at", TS, nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_work_batches"),
        sa.UniqueConstraint(
            "study_id",
            "stage_index",
            "batch_index",
            name="uq_work_batches_study_id_stage_index_batch_index",
        ),
        sa.ForeignKeyConstraint(
            ["study_id"],
            ["studies.id"],
            name="fk_work_batches_study_id_studies",
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["study_id", "stage_index"],
            ["stages.study_id", "stages.stage_index"],
            name="fk_work_batches_study_id_stage_index_stages",
            ondelete="CASCADE",
        ),
        sa.CheckConstraint(
            _in("status", ("pending", "leased", "done", "failed")), name="ck_work_batches_status"
        ),
        sa.CheckConstraint("chain_start <= chain_stop", name="ck_work_batches_chain_range"),
    )
    op.create_index(
        "ix_work_batches_status_lease_expires_at", "work_batches", ["status", "lease_expires_at"]
    )

    op.create_table(
        "samples",
        sa.Column("stage_id", ID, nullable=False),
        sa.Column("sample_index", sa.Integer(), nullable=False),
        sa.Column("params", sa.LargeBinary(), nullable=False),
        sa.Column("responses", sa.LargeBinary(), nullable=True),
        sa.Column("log_likelihood", sa.Double(), nullable=True),
        sa.Column("log_prior", sa.Double(), nullable=True),
        sa.PrimaryKeyConstraint("stage_id", "sample_index", name="pk_samples"),
        sa.ForeignKeyConstraint(
            ["stage_id"], ["stages.id"], name="fk_samples_stage_id_stages", ondelete="CASCADE"
        ),
    )

    op.create_table(
        "events",
        sa.Column("id", ID, nullable=False),
        sa.Column("study_id", ID, nullable=True),
        sa.Column("created_at", TS, nullable=False),
        sa.Column("kind", sa.String(64), nullable=False),
        sa.Column("payload", JSON, nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_events"),
        sa.ForeignKeyConstraint(
            ["study_id"], ["studies.id"], name="fk_events_study_id_studies", ondelete="CASCADE"
        ),
    )
    op.create_index("ix_events_study_id_id", "events", ["study_id", "id"])


def downgrade() -> None:
    op.drop_index("ix_events_study_id_id", table_name="events")
    op.drop_table("events")
    op.drop_table("samples")
    op.drop_index("ix_work_batches_status_lease_expires_at", table_name="work_batches")
    op.drop_table("work_batches")
    op.drop_table("stages")
    op.drop_index("ix_study_datasets_dataset_id", table_name="study_datasets")
    op.drop_table("study_datasets")
    op.drop_index("ix_studies_status_id", table_name="studies")
    op.drop_table("studies")
    op.drop_table("datasets")
