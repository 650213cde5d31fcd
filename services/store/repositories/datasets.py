"""Uploaded SWT datasets: immutable, unique by content hash.

A dataset row holds the upload metadata (``meta``: whatever the uploader sent besides the
file) and the processed dataset (``processed``: ``SWTDataset.to_dict(include_series=False)``:
conditions, provenance, steady means, standard errors and processing parameters). The bytes as
uploaded (optional for datasets built in code) are rows of ``dataset_chunks`` of at most 1 MiB
each. The filtered series are not stored; they are recomputed from the raw bytes when needed.
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping
from typing import Any, BinaryIO

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from scm_core.signals import SWTDataset

from ..errors import NotFoundError
from ..models import Dataset, DatasetChunk, DatasetUpload
from ..records import DatasetRecord, Page
from .base import Database
from .events import append_event

__all__ = ["DatasetRepository"]

#: largest piece of a dataset's raw bytes in one row
RAW_CHUNK_BYTES = 1 << 20
_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
_LIST_COLUMNS = list(Dataset.__table__.c)


def _record(row: Any) -> DatasetRecord:
    return DatasetRecord(
        id=row.id,
        content_hash=row.content_hash,
        name=row.name,
        source_kind=row.source_kind,
        filename=row.filename,
        media_type=row.media_type,
        size_bytes=row.size_bytes,
        meta=dict(row.meta or {}),
        processed=dict(row.processed),
        created_at=row.created_at,
    )


def _restore_floats(processed: dict[str, Any]) -> dict[str, Any]:
    """Undo the JSON column's encoding of non-finite floats in the numeric fields."""

    def num(v: Any) -> Any:
        return _NONFINITE[v] if isinstance(v, str) and v in _NONFINITE else v

    out = dict(processed)
    out["responses"] = {
        k: {f: num(v) for f, v in stat.items()} for k, stat in processed["responses"].items()
    }
    for key in ("rate_hz", "offset", "cutoff_hz"):
        if key in out:
            out[key] = num(out[key])
    if out.get("window") is not None:
        out["window"] = [num(v) for v in out["window"]]
    return out


def _insert_ignore(session: Session, model: Any, key: str, values: dict[str, Any]) -> bool:
    """INSERT ... ON CONFLICT (key) DO NOTHING; True when a row was inserted."""
    dialect = session.get_bind().dialect.name
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    stmt = (
        insert(model)
        .values(**values)
        .on_conflict_do_nothing(index_elements=[key])
        .returning(model.__table__.c[key])
    )
    return session.execute(stmt).scalar_one_or_none() is not None


def _write_chunks(session: Session, dataset_id: int, stream: BinaryIO) -> None:
    """Store ``stream`` as ``dataset_chunks`` rows of at most 1 MiB."""
    seq = 0
    while chunk := stream.read(RAW_CHUNK_BYTES):
        session.execute(sa.insert(DatasetChunk).values(dataset_id=dataset_id, seq=seq, data=chunk))
        seq += 1


class DatasetRepository:
    def __init__(self, db: Database) -> None:
        self.db = db

    def add(
        self,
        dataset: SWTDataset,
        raw: bytes | BinaryIO | None = None,
        *,
        meta: Mapping[str, Any] | None = None,
        filename: str | None = None,
        media_type: str | None = None,
        upload_hash: str | None = None,
    ) -> tuple[DatasetRecord, bool]:
        """Store a dataset unless one with the same content hash exists.

        Returns (record, created). An identical re-upload (same ``dataset.content_hash``)
        returns the existing row unchanged and created=False, also under concurrent uploads.
        ``upload_hash`` (the upload as sent) is recorded for :meth:`find_upload`. ``raw`` (bytes
        or a seekable binary file) is stored in pieces of 1 MiB, never held whole.
        """
        if not dataset.content_hash:
            raise ValueError("dataset has no content_hash")
        now = self.db.now()
        stream = io.BytesIO(raw) if isinstance(raw, bytes | bytearray) else raw
        size = 0
        if stream is not None:
            size = stream.seek(0, io.SEEK_END)
            stream.seek(0)
        values = {
            "content_hash": dataset.content_hash,
            "name": dataset.name[:200],
            "source_kind": dataset.source_kind,
            "filename": filename,
            "media_type": media_type,
            "size_bytes": size,
            "meta": dict(meta or {}),
            "processed": dataset.to_dict(include_series=False),
            "created_at": now,
        }
        with self.db.write() as s:
            created = _insert_ignore(s, Dataset, "content_hash", values)
            row = s.execute(
                sa.select(*_LIST_COLUMNS).where(Dataset.content_hash == dataset.content_hash)
            ).one()
            if created and stream is not None:
                _write_chunks(s, row.id, stream)
            if created:
                append_event(
                    s,
                    None,
                    "dataset_added",
                    {"dataset_id": row.id, "content_hash": dataset.content_hash},
                    now,
                )
            if upload_hash is not None:
                upload = {"upload_hash": upload_hash, "dataset_id": row.id, "created_at": now}
                _insert_ignore(s, DatasetUpload, "upload_hash", upload)
            return _record(row), created

    def get(self, dataset_id: int) -> DatasetRecord:
        with self.db.read() as s:
            row = s.execute(sa.select(*_LIST_COLUMNS).where(Dataset.id == dataset_id)).first()
        if row is None:
            raise NotFoundError(f"dataset {dataset_id} not found")
        return _record(row)

    def get_by_hash(self, content_hash: str) -> DatasetRecord | None:
        with self.db.read() as s:
            row = s.execute(
                sa.select(*_LIST_COLUMNS).where(Dataset.content_hash == content_hash)
            ).first()
        return None if row is None else _record(row)

    def find_upload(self, upload_hash: str) -> DatasetRecord | None:
        """The dataset an identical earlier upload gave (same bytes, metadata and offset)."""
        with self.db.read() as s:
            row = s.execute(
                sa.select(*_LIST_COLUMNS)
                .join(DatasetUpload, DatasetUpload.dataset_id == Dataset.id)
                .where(DatasetUpload.upload_hash == upload_hash)
            ).first()
        return None if row is None else _record(row)

    def load(self, dataset_id: int) -> SWTDataset:
        """The processed dataset (without series) as an SWTDataset."""
        return SWTDataset.from_dict(_restore_floats(self.get(dataset_id).processed))

    def raw(self, dataset_id: int) -> bytes | None:
        """The bytes as uploaded (None for datasets stored without them)."""
        with self.db.read() as s:
            if s.scalar(sa.select(Dataset.id).where(Dataset.id == dataset_id)) is None:
                raise NotFoundError(f"dataset {dataset_id} not found")
            chunks = s.scalars(
                sa.select(DatasetChunk.data)
                .where(DatasetChunk.dataset_id == dataset_id)
                .order_by(DatasetChunk.seq)
            ).all()
        return b"".join(chunks) if chunks else None

    def list(self, *, limit: int = 50, offset: int = 0) -> Page[DatasetRecord]:
        """Datasets, newest first."""
        with self.db.read() as s:
            total = s.scalar(sa.select(sa.func.count()).select_from(Dataset)) or 0
            rows = s.execute(
                sa.select(*_LIST_COLUMNS)
                .order_by(Dataset.id.desc())
                .limit(max(int(limit), 0))
                .offset(max(int(offset), 0))
            ).all()
        return Page([_record(r) for r in rows], int(total), limit, offset)
