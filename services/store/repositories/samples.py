"""Posterior samples: one row per sample of a done stage.

``params`` and ``responses`` are float64 bytes (bit-exact). ``log_likelihood`` and ``log_prior``
are double columns (queryable; -inf and +inf stored as such, NaN as NULL and read back as NaN).
SQLite stores a REAL -0.0 as 0.0, so on SQLite these two columns lose the sign of a zero
(numerically equal; nothing in TMCMC depends on it); PostgreSQL keeps it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from ..codec import f64_bytes, f64_matrix
from ..errors import NotFoundError
from ..models import Sample, Stage
from ..records import SampleArrays, SamplePage
from .base import Database

__all__ = ["SampleRepository", "fetch_arrays", "insert_samples"]

INSERT_CHUNK = 5000


def insert_samples(session: Session, stage_id: int, state: SampleArrays) -> int:
    """Bulk-insert the population ``state`` under stage ``stage_id`` (caller's tx)."""
    X = np.asarray(state.samples, dtype=np.float64)
    ll = np.asarray(state.log_likelihood, dtype=np.float64)
    lp = np.asarray(state.log_prior, dtype=np.float64)
    R = None if state.responses is None else np.asarray(state.responses, dtype=np.float64)
    n = X.shape[0]
    if ll.shape != (n,) or lp.shape != (n,) or (R is not None and R.shape[0] != n):
        raise ValueError("samples, log_likelihood, log_prior and responses disagree in length")
    rows: list[dict[str, Any]] = [
        {
            "stage_id": stage_id,
            "sample_index": i,
            "params": f64_bytes(X[i]),
            "responses": None if R is None else f64_bytes(R[i]),
            "log_likelihood": float(ll[i]),
            "log_prior": float(lp[i]),
        }
        for i in range(n)
    ]
    for start in range(0, n, INSERT_CHUNK):
        session.execute(sa.insert(Sample), rows[start : start + INSERT_CHUNK])
    return n


def _nan(values: list[float | None]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def fetch_arrays(
    session: Session, stage_id: int, start: int = 0, stop: int | None = None
) -> SampleArrays:
    """Rows ``start <= sample_index < stop`` of a stage as numpy arrays (caller's tx)."""
    q = (
        sa.select(Sample.params, Sample.responses, Sample.log_likelihood, Sample.log_prior)
        .where(Sample.stage_id == stage_id, Sample.sample_index >= start)
        .order_by(Sample.sample_index)
    )
    if stop is not None:
        q = q.where(Sample.sample_index < stop)
    rows = session.execute(q).all()
    params = [r[0] for r in rows]
    resp = [r[1] for r in rows]
    responses = None if not rows or any(r is None for r in resp) else f64_matrix(resp)
    return SampleArrays(
        samples=f64_matrix(params),
        log_likelihood=_nan([r[2] for r in rows]),
        log_prior=_nan([r[3] for r in rows]),
        responses=responses,
    )


def stage_id_of(session: Session, study_id: int, stage_index: int) -> int:
    sid = session.scalar(
        sa.select(Stage.id).where(Stage.study_id == study_id, Stage.stage_index == stage_index)
    )
    if sid is None:
        raise NotFoundError(f"stage {stage_index} of study {study_id} not found")
    return int(sid)


#: the largest sample index (an INTEGER column)
_INDEX_MAX = 2**31 - 1


class SampleRepository:
    def __init__(self, db: Database) -> None:
        self.db = db

    def count(self, study_id: int, stage_index: int) -> int:
        with self.db.read() as s:
            sid = stage_id_of(s, study_id, stage_index)
            return int(s.scalar(sa.select(sa.func.count()).where(Sample.stage_id == sid)) or 0)

    def arrays(self, study_id: int, stage_index: int) -> SampleArrays:
        """The whole population of a stage (empty arrays before the stage is done)."""
        with self.db.read() as s:
            return fetch_arrays(s, stage_id_of(s, study_id, stage_index))

    def page(
        self, study_id: int, stage_index: int, *, start: int = 0, limit: int = 500
    ) -> SamplePage:
        """Samples ``start`` .. ``start + limit - 1`` (keyset on the sample index; bounds past
        the column's largest value are clipped to it, where no sample can be)."""
        start = min(max(int(start), 0), _INDEX_MAX)
        end = min(start + max(int(limit), 0), _INDEX_MAX)
        with self.db.read() as s:
            sid = stage_id_of(s, study_id, stage_index)
            total = int(s.scalar(sa.select(sa.func.count()).where(Sample.stage_id == sid)) or 0)
            arrays = fetch_arrays(s, sid, start, end)
        return SamplePage(start=start, total=total, arrays=arrays)
