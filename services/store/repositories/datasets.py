"""Uploaded SWT datasets: immutable, unique by content hash.

A dataset row holds the bytes as uploaded (``raw``, optional for datasets built in code), the
upload metadata (``meta``: whatever the uploader sent besides the file), and the processed
dataset (``processed``: ``SWTDataset.to_dict(include_series=False)``: conditions, provenance,
steady means, standard errors and processing parameters). The filtered series are not stored;
they are recomputed from ``raw`` when needed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from scm_core.signals import SWTDataset

from ..engine import jsonable
from ..errors import NotFoundError
from ..models import Dataset
from ..records import DatasetRecord, Page
from .base import Database
from .events import append_event

__all__ = ["DatasetRepository"]

_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
_LIST_COLUMNS = [c for c in Dataset.__table__.c if c.key != "raw"]


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


def _insert_ignore(session: Session, values: dict[str, Any]) -> int | None:
    """INSERT ... ON CONFLICT (content_hash) DO NOTHING RETURNING id."""
    dialect = session.get_bind().dialect.name
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    stmt = (
        insert(Dataset)
        .values(**values)
        .on_conflict_do_nothing(index_elements=["content_hash"])
        .returning(Dataset.id)
    )
    return session.execute(stmt).scalar_one_or_none()


class DatasetRepository:
    def __init__(self, db: Database) -> None:
        self.db = db

    def add(
        self,
        dataset: SWTDataset,
        raw: bytes | None = None,
        *,
        meta: Mapping[str, Any] | None = None,
        filename: str | None = None,
        media_type: str | None = None,
    ) -> tuple[DatasetRecord, bool]:
        """Store a dataset unless one with the same content hash exists.

        Returns (record, created). An identical re-upload (same ``dataset.content_hash``)
        returns the existing row unchanged and created=False, also under concurrent uploads.
        """
        if not dataset.content_hash:
            raise ValueError("dataset has no content_hash")
        now = self.db.now()
        values = {
            "content_hash": dataset.content_hash,
            "name": dataset.name[:200],
            "source_kind": dataset.source_kind,
            "filename": filename,
            "media_type": media_type,
            "size_bytes": len(raw) if raw is not None else 0,
            "raw": raw,
            "meta": jsonable(dict(meta or {})),
            "processed": jsonable(dataset.to_dict(include_series=False)),
            "created_at": now,
        }
        with self.db.write() as s:
            new_id = _insert_ignore(s, values)
            if new_id is not None:
                append_event(
                    s,
                    None,
                    "dataset_added",
                    {"dataset_id": new_id, "content_hash": dataset.content_hash},
                    now,
                )
            row = s.execute(
                sa.select(*_LIST_COLUMNS).where(Dataset.content_hash == dataset.content_hash)
            ).one()
            return _record(row), new_id is not None

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

    def load(self, dataset_id: int) -> SWTDataset:
        """The processed dataset (without series) as an SWTDataset."""
        return SWTDataset.from_dict(_restore_floats(self.get(dataset_id).processed))

    def raw(self, dataset_id: int) -> bytes | None:
        """The bytes as uploaded (None for datasets stored without them)."""
        with self.db.read() as s:
            row = s.execute(sa.select(Dataset.raw).where(Dataset.id == dataset_id)).first()
        if row is None:
            raise NotFoundError(f"dataset {dataset_id} not found")
        return row.raw

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
