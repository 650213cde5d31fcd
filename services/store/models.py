"""SQLAlchemy models: the database owns study state (datasets, studies, stages, batches, samples,
events). The schema is created by the Alembic migrations in ``migrations/``, never by
``create_all`` in production; ``tests/store`` checks that models and migrations agree.

Arrays are stored compactly: sample parameter vectors and responses as little-endian float64
bytes per row, stage plans and batch results as ``.npz`` blobs (see :mod:`.codec`), so -inf and
NaN survive exactly. Timestamps are aware UTC datetimes.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, get_args, get_type_hints

import sqlalchemy as sa
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

from .records import StageRecord, stage_columns
from .types import BigIntId, JSONType, Real, UTCDateTime, utcnow

__all__ = [
    "BATCH_STATUSES",
    "STAGE_STATUSES",
    "STUDY_ACTIVE",
    "STUDY_FINAL",
    "STUDY_KIND_PATTERN",
    "STUDY_STATUSES",
    "Base",
    "Dataset",
    "DatasetChunk",
    "DatasetUpload",
    "Event",
    "Heartbeat",
    "Sample",
    "Stage",
    "Study",
    "StudyDataset",
    "WorkBatch",
]

#: a study kind's name: the registry of ``services.studies.kinds`` says which exist
STUDY_KIND_PATTERN = r"^[a-z][a-z0-9_]{0,15}$"
STUDY_STATUSES = ("queued", "running", "completed", "failed", "cancelled", "stalled")
STUDY_ACTIVE = ("queued", "running")
#: the kind of the rows from before studies had kinds: the server default (0002, named by 0011), a
#: fact of the schema (the store knows no kind otherwise)
PRE_KIND_ROWS = "calibration"
STUDY_FINAL = ("completed", "failed", "cancelled", "stalled")
STAGE_STATUSES = ("planned", "running", "reducing", "done")
BATCH_STATUSES = ("pending", "leased", "done", "failed")
SOURCE_KINDS = ("timeseries", "summary")

NAMING_CONVENTION = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_N_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


def _in(column: str, values: tuple[str, ...]) -> str:
    return f"{column} IN ({', '.join(repr(v) for v in values)})"


class Base(DeclarativeBase):
    metadata = sa.MetaData(naming_convention=NAMING_CONVENTION)


class Dataset(Base):
    """An uploaded SWT dataset; immutable, identified by its content hash."""

    __tablename__ = "datasets"
    __table_args__ = (sa.CheckConstraint(_in("source_kind", SOURCE_KINDS), name="source_kind"),)

    id: Mapped[int] = mapped_column(BigIntId, primary_key=True)
    content_hash: Mapped[str] = mapped_column(sa.String(64), unique=True)
    name: Mapped[str] = mapped_column(sa.String(200))
    source_kind: Mapped[str] = mapped_column(sa.String(16))
    filename: Mapped[str | None] = mapped_column(sa.String(255))
    media_type: Mapped[str | None] = mapped_column(sa.String(100))
    size_bytes: Mapped[int] = mapped_column(sa.BigInteger)
    meta: Mapped[dict[str, Any]] = mapped_column(JSONType)
    processed: Mapped[dict[str, Any]] = mapped_column(JSONType)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class DatasetChunk(Base):
    """The bytes of a dataset as uploaded, in pieces of at most 1 MiB (``seq`` 0, 1, ...), so
    that large logs are written and read without holding them whole, on SQLite and PostgreSQL
    alike."""

    __tablename__ = "dataset_chunks"

    dataset_id: Mapped[int] = mapped_column(
        BigIntId, sa.ForeignKey("datasets.id", ondelete="CASCADE"), primary_key=True
    )
    seq: Mapped[int] = mapped_column(sa.Integer, primary_key=True)
    data: Mapped[bytes] = mapped_column(sa.LargeBinary)


class DatasetUpload(Base):
    """The hash of an upload as sent (raw bytes, metadata field, offset) and the dataset it
    gave, so an identical re-upload is answered before any parsing. Several uploads (line
    endings, BOM, metadata in the file or in the field) may give one dataset."""

    __tablename__ = "dataset_uploads"

    upload_hash: Mapped[str] = mapped_column(sa.String(64), primary_key=True)
    dataset_id: Mapped[int] = mapped_column(
        BigIntId, sa.ForeignKey("datasets.id", ondelete="CASCADE"), index=True
    )
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class Study(Base):
    """A study: its case document, datasets, seed and progress.

    ``kind`` names the plug-in that runs it (``services.studies.kinds``: a calibration's stages
    of TMCMC chains, a screening's one stage whose "chains" are the Morris design points ...;
    the column's server default is what rows from before kinds were). ``case_spec`` is the
    single source of what the study is (priors, sampler and simulator settings are derived from
    it by the kind when read); ``payload``: the kind's own settings (JSON: the study an update
    starts from, a screening's design), ``result``: what the kind stores when the study ends.
    ``version`` goes up with every change of the study's state (each event appended for it, a
    stage starting): the API's ETags.
    """

    __tablename__ = "studies"
    __table_args__ = (
        sa.CheckConstraint(_in("status", STUDY_STATUSES), name="status"),
        sa.Index("ix_studies_status_id", "status", "id"),
        sa.Index("ix_studies_kind_id", "kind", "id"),
    )

    id: Mapped[int] = mapped_column(BigIntId, primary_key=True)
    kind: Mapped[str] = mapped_column(sa.String(16), server_default=PRE_KIND_ROWS)
    name: Mapped[str] = mapped_column(sa.String(200))
    status: Mapped[str] = mapped_column(sa.String(16), default="queued")
    case_spec: Mapped[dict[str, Any]] = mapped_column(JSONType)
    seed: Mapped[int] = mapped_column(sa.BigInteger)
    n_samples: Mapped[int] = mapped_column(sa.Integer)
    batch_size: Mapped[int | None] = mapped_column(sa.Integer)
    current_stage: Mapped[int | None] = mapped_column(sa.Integer)
    log_evidence: Mapped[float | None] = mapped_column(Real)
    log_evidence_var: Mapped[float | None] = mapped_column(Real)
    model_runs: Mapped[int] = mapped_column(sa.BigInteger, default=0)
    failed_runs: Mapped[int] = mapped_column(sa.BigInteger, default=0)
    error: Mapped[str | None] = mapped_column(sa.Text)
    result: Mapped[dict[str, Any] | None] = mapped_column(JSONType)
    payload: Mapped[dict[str, Any] | None] = mapped_column(JSONType)
    version: Mapped[int] = mapped_column(sa.BigInteger, default=0, server_default=sa.text("0"))
    #: repeated runs submitted together: the id of the group's first study (NULL: alone)
    run_group: Mapped[int | None] = mapped_column(sa.BigInteger, index=True)
    #: the study this one starts from (an update's earlier study, a prediction's posterior)
    parent_id: Mapped[int | None] = mapped_column(sa.BigInteger, index=True)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class StudyDataset(Base):
    """Datasets of a study, in likelihood order (``position``)."""

    __tablename__ = "study_datasets"
    __table_args__ = (sa.UniqueConstraint("study_id", "dataset_id"),)

    study_id: Mapped[int] = mapped_column(
        sa.ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True
    )
    position: Mapped[int] = mapped_column(sa.Integer, primary_key=True)
    dataset_id: Mapped[int] = mapped_column(
        sa.ForeignKey("datasets.id", ondelete="RESTRICT"), index=True
    )


def _stage_columns() -> type:
    """A declarative mixin with a stage's own columns, as :class:`.records.StageRecord`
    declares them (:func:`.records.stage_columns`: name, SQL type, nullable from the field's
    type)."""
    sql = {"real": Real, "int": sa.Integer, "bigint": sa.BigInteger}
    hints = get_type_hints(StageRecord)
    columns = {
        f.name: mapped_column(
            sql[f.metadata["column"]], nullable=type(None) in get_args(hints[f.name])
        )
        for f in stage_columns()
    }
    return type("StageColumns", (), columns)


class Stage(_stage_columns(), Base):
    """One TMCMC stage of a study: its plan, diagnostics (the columns
    :class:`.records.StageRecord` declares) and, once done, its population."""

    __tablename__ = "stages"
    __table_args__ = (
        sa.UniqueConstraint("study_id", "stage_index"),
        sa.CheckConstraint(_in("status", STAGE_STATUSES), name="status"),
    )

    id: Mapped[int] = mapped_column(BigIntId, primary_key=True)
    study_id: Mapped[int] = mapped_column(sa.ForeignKey("studies.id", ondelete="CASCADE"))
    stage_index: Mapped[int] = mapped_column(sa.Integer)
    status: Mapped[str] = mapped_column(sa.String(16))
    plan: Mapped[bytes | None] = mapped_column(sa.LargeBinary, deferred=True)
    state_meta: Mapped[dict[str, Any] | None] = mapped_column(JSONType)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class WorkBatch(Base):
    """A batch of chains (or of stage-0 points) of one stage: the unit of leased work."""

    __tablename__ = "work_batches"
    __table_args__ = (
        sa.UniqueConstraint("study_id", "stage_index", "batch_index"),
        sa.ForeignKeyConstraint(
            ["study_id", "stage_index"],
            ["stages.study_id", "stages.stage_index"],
            ondelete="CASCADE",
        ),
        sa.CheckConstraint(_in("status", BATCH_STATUSES), name="status"),
        sa.CheckConstraint("chain_start <= chain_stop", name="chain_range"),
        sa.Index("ix_work_batches_status_lease_expires_at", "status", "lease_expires_at"),
    )

    id: Mapped[int] = mapped_column(BigIntId, primary_key=True)
    study_id: Mapped[int] = mapped_column(sa.ForeignKey("studies.id", ondelete="CASCADE"))
    stage_index: Mapped[int] = mapped_column(sa.Integer)
    batch_index: Mapped[int] = mapped_column(sa.Integer)
    chain_start: Mapped[int] = mapped_column(sa.Integer)
    chain_stop: Mapped[int] = mapped_column(sa.Integer)
    status: Mapped[str] = mapped_column(sa.String(16), default="pending")
    attempts: Mapped[int] = mapped_column(sa.Integer, default=0)
    worker_id: Mapped[str | None] = mapped_column(sa.String(200))
    leased_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    lease_expires_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    heartbeat_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    dispatched_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    result: Mapped[bytes | None] = mapped_column(sa.LargeBinary, deferred=True)
    error: Mapped[str | None] = mapped_column(sa.Text)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    #: model runs of the stored result (None: as planned for the batch's items)
    model_runs: Mapped[int | None] = mapped_column(sa.BigInteger)


class Sample(Base):
    """One sample of a stage's population; ``params``/``responses`` are float64 bytes."""

    __tablename__ = "samples"

    stage_id: Mapped[int] = mapped_column(
        sa.ForeignKey("stages.id", ondelete="CASCADE"), primary_key=True
    )
    sample_index: Mapped[int] = mapped_column(sa.Integer, primary_key=True)
    params: Mapped[bytes] = mapped_column(sa.LargeBinary)
    responses: Mapped[bytes | None] = mapped_column(sa.LargeBinary)
    log_likelihood: Mapped[float | None] = mapped_column(Real)
    log_prior: Mapped[float | None] = mapped_column(Real)


class Event(Base):
    """Append-only log: what happened to a study (or, with no study, to the service)."""

    __tablename__ = "events"
    __table_args__ = (sa.Index("ix_events_study_id_id", "study_id", "id"),)

    id: Mapped[int] = mapped_column(BigIntId, primary_key=True)
    study_id: Mapped[int | None] = mapped_column(sa.ForeignKey("studies.id", ondelete="CASCADE"))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    kind: Mapped[str] = mapped_column(sa.String(64))
    payload: Mapped[dict[str, Any]] = mapped_column(JSONType)


@sa.event.listens_for(Event, "before_update")
def _event_update(mapper: Any, connection: Any, target: Event) -> None:
    raise TypeError("events are append-only")


@sa.event.listens_for(Event, "before_delete")
def _event_delete(mapper: Any, connection: Any, target: Event) -> None:
    raise TypeError("events are append-only")


class Heartbeat(Base):
    """A row a server commits to prove the database takes writes (``/health/ready``)."""

    __tablename__ = "heartbeats"

    name: Mapped[str] = mapped_column(sa.String(64), primary_key=True)
    beat_at: Mapped[datetime] = mapped_column(UTCDateTime)
    beats: Mapped[int] = mapped_column(sa.BigInteger)
