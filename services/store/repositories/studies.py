"""Studies: creation, listing, start, cancel and failure.

Status: queued -> running -> completed | stalled | failed, and queued/running -> cancelled |
failed. Every status change is a compare-and-set (``UPDATE ... WHERE status IN (...)``), so a
cancel racing with a stage advance or with the reaper has exactly one winner.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from services.limits import seed_error

from ..errors import NotFoundError
from ..models import STUDY_ACTIVE, STUDY_KIND_PATTERN, STUDY_STATUSES, Dataset, Study, StudyDataset
from ..records import Page, PlannedStage, StageRecord, StudyRecord, StudySpec
from .base import Database
from .events import append_event
from .stage_rows import create_stage, stage_record

__all__ = ["StudyRepository", "fail_study", "load_study", "set_study_status"]


def _dataset_ids(session: Session, study_ids: Iterable[int]) -> dict[int, tuple[int, ...]]:
    ids = list(study_ids)
    out: dict[int, list[int]] = {i: [] for i in ids}
    if ids:
        rows = session.execute(
            sa.select(StudyDataset.study_id, StudyDataset.dataset_id)
            .where(StudyDataset.study_id.in_(ids))
            .order_by(StudyDataset.study_id, StudyDataset.position)
        )
        for study_id, dataset_id in rows:
            out[study_id].append(dataset_id)
    return {k: tuple(v) for k, v in out.items()}


def _record(st: Study, dataset_ids: tuple[int, ...]) -> StudyRecord:
    return StudyRecord(
        id=st.id,
        kind=st.kind,
        name=st.name,
        status=st.status,
        case=dict(st.case_spec),
        seed=int(st.seed),
        n_samples=st.n_samples,
        batch_size=st.batch_size,
        dataset_ids=dataset_ids,
        current_stage=st.current_stage,
        log_evidence=st.log_evidence,
        log_evidence_var=st.log_evidence_var,
        model_runs=int(st.model_runs),
        failed_runs=int(st.failed_runs),
        error=st.error,
        created_at=st.created_at,
        updated_at=st.updated_at,
        started_at=st.started_at,
        finished_at=st.finished_at,
        result=None if st.result is None else dict(st.result),
        payload=None if st.payload is None else dict(st.payload),
        version=int(st.version or 0),
        run_group=None if st.run_group is None else int(st.run_group),
        parent_id=None if st.parent_id is None else int(st.parent_id),
    )


def load_study(session: Session, study_id: int) -> StudyRecord:
    """The study as a record, read in the caller's transaction."""
    st = session.get(Study, study_id, populate_existing=True)
    if st is None:
        raise NotFoundError(f"study {study_id} not found")
    return _record(st, _dataset_ids(session, [study_id])[study_id])


def set_study_status(
    session: Session,
    study_id: int,
    to: str,
    now: datetime,
    *,
    from_: Sequence[str] = STUDY_ACTIVE,
    **values: Any,
) -> bool:
    """Compare-and-set of a study's status; True if this call changed it."""
    if to not in STUDY_STATUSES:
        raise ValueError(f"unknown study status {to!r}")
    values.setdefault("updated_at", now)
    if to not in STUDY_ACTIVE:
        values.setdefault("finished_at", now)
    res = session.execute(
        sa.update(Study)
        .where(Study.id == study_id, Study.status.in_(list(from_)))
        .values(status=to, **values)
        .execution_options(synchronize_session=False)
    )
    return res.rowcount == 1


def fail_study(
    session: Session, study_id: int, error: str, now: datetime, payload: dict[str, Any] | None
) -> bool:
    """Mark an active study failed with ``error`` and log "study_failed" (caller's tx)."""
    if not set_study_status(session, study_id, "failed", now, error=error):
        return False
    append_event(session, study_id, "study_failed", {"error": error, **(payload or {})}, now)
    return True


def _check_kind(kind: str) -> None:
    """A kind's name is an identifier (which kinds exist is the study service's registry)."""
    if not isinstance(kind, str) or not re.match(STUDY_KIND_PATTERN, kind):
        raise ValueError(f"study kind must match {STUDY_KIND_PATTERN}, got {kind!r}")


def _list_filter(
    status: str | Sequence[str] | None, kind: str | None, parent: int | None = None
) -> list[Any]:
    where: list[Any] = []
    if kind is not None:
        _check_kind(kind)
        where.append(Study.kind == kind)
    if parent is not None:
        where.append(Study.parent_id == int(parent))
    if status is not None:
        statuses = [status] if isinstance(status, str) else list(status)
        unknown = set(statuses) - set(STUDY_STATUSES)
        if unknown:
            raise ValueError(f"unknown study status(es) {sorted(unknown)}")
        where.append(Study.status.in_(statuses))
    return where


class StudyRepository:
    def __init__(self, db: Database) -> None:
        self.db = db

    def create(self, spec: StudySpec) -> StudyRecord:
        """Insert a queued study with its datasets (in order) and a "study_created" event."""
        if why := seed_error(spec.seed):
            raise ValueError(f"seed: {why}")
        _check_kind(spec.kind)
        if int(spec.n_samples) < 1:
            raise ValueError(f"n_samples must be >= 1, got {spec.n_samples}")
        if spec.batch_size is not None and int(spec.batch_size) < 1:
            raise ValueError(f"batch_size must be >= 1 or None, got {spec.batch_size}")
        dataset_ids = [int(i) for i in spec.dataset_ids]
        if len(set(dataset_ids)) != len(dataset_ids):
            raise ValueError(f"dataset ids repeat: {dataset_ids}")
        now = self.db.now()
        with self.db.write() as s:
            if dataset_ids:
                found = set(s.scalars(sa.select(Dataset.id).where(Dataset.id.in_(dataset_ids))))
                missing = [i for i in dataset_ids if i not in found]
                if missing:
                    raise NotFoundError(f"datasets not found: {missing}")
            st = Study(
                kind=spec.kind,
                name=spec.name[:200],
                status="queued",
                case_spec=dict(spec.case),
                payload=None if spec.payload is None else dict(spec.payload),
                parent_id=None if spec.parent_id is None else int(spec.parent_id),
                seed=int(spec.seed),
                n_samples=int(spec.n_samples),
                batch_size=None if spec.batch_size is None else int(spec.batch_size),
                model_runs=0,
                failed_runs=0,
                created_at=now,
                updated_at=now,
            )
            s.add(st)
            s.flush()
            s.add_all(
                StudyDataset(study_id=st.id, position=i, dataset_id=d)
                for i, d in enumerate(dataset_ids)
            )
            append_event(
                s,
                st.id,
                "study_created",
                {"name": st.name, "kind": st.kind, "dataset_ids": dataset_ids},
                now,
            )
            s.flush()
            s.refresh(st, ["version", "updated_at"])  # raised by the event
            return _record(st, tuple(dataset_ids))

    def get(self, study_id: int) -> StudyRecord:
        with self.db.read() as s:
            return load_study(s, study_id)

    def group_runs(self, study_ids: Sequence[int]) -> None:
        """Mark ``study_ids`` (two or more) as one group of repeated runs: their ``run_group``
        becomes the first id. One transaction; raises NotFoundError if one is missing."""
        ids = [int(i) for i in study_ids]
        if len(ids) < 2 or len(set(ids)) != len(ids):
            raise ValueError(f"a run group needs two or more distinct studies, got {ids}")
        with self.db.write() as s:
            found = s.execute(sa.update(Study).where(Study.id.in_(ids)).values(run_group=ids[0]))
            if found.rowcount != len(ids):
                raise NotFoundError(f"studies not found among {ids}")

    def run_group(self, group: int) -> list[int]:
        """The ids of the studies of run group ``group``, in order."""
        with self.db.read() as s:
            rows = s.scalars(sa.select(Study.id).where(Study.run_group == group).order_by(Study.id))
            return [int(i) for i in rows]

    def version(self, study_id: int) -> int:
        """The study's version (raised by every change of its state); one indexed read."""
        with self.db.read() as s:
            v = s.scalar(sa.select(Study.version).where(Study.id == study_id))
        if v is None:
            raise NotFoundError(f"study {study_id} not found")
        return int(v)

    def list(
        self,
        status: str | Sequence[str] | None = None,
        *,
        kind: str | None = None,
        parent: int | None = None,
        limit: int = 50,
        offset: int = 0,
    ) -> Page[StudyRecord]:
        """Studies, newest first, optionally only those with the given status(es), kind or
        parent study (those made from study ``parent``: one indexed query)."""
        where = _list_filter(status, kind, parent)
        with self.db.read() as s:
            total = s.scalar(sa.select(sa.func.count()).select_from(Study).where(*where)) or 0
            studies = list(
                s.scalars(
                    sa.select(Study)
                    .where(*where)
                    .order_by(Study.id.desc())
                    .limit(max(int(limit), 0))
                    .offset(max(int(offset), 0))
                )
            )
            ids = _dataset_ids(s, [st.id for st in studies])
            items = [_record(st, ids[st.id]) for st in studies]
        return Page(items, int(total), limit, offset)

    def list_versions(
        self,
        status: str | Sequence[str] | None = None,
        *,
        kind: str | None = None,
        parent: int | None = None,
        limit: int = 50,
        offset: int = 0,
    ) -> tuple[int, list[tuple[int, int]]]:
        """(total, [(id, version)]) of the page :meth:`list` would give: equal answers mean an
        unchanged page (a study's datasets never change). Reads the studies table only."""
        where = _list_filter(status, kind, parent)
        with self.db.read() as s:
            total = s.scalar(sa.select(sa.func.count()).select_from(Study).where(*where)) or 0
            rows = s.execute(
                sa.select(Study.id, Study.version)
                .where(*where)
                .order_by(Study.id.desc())
                .limit(max(int(limit), 0))
                .offset(max(int(offset), 0))
            ).all()
        return int(total), [(int(i), int(v)) for i, v in rows]

    def stuck_queued(self, older_than: float) -> list[int]:
        """Ids of studies still ``queued`` ``older_than`` seconds after their creation (their
        submitter died between storing and starting them), oldest first."""
        cutoff = self.db.now() - self.db.lease_delta(older_than)
        with self.db.read() as s:
            return [
                int(i)
                for i in s.scalars(
                    sa.select(Study.id)
                    .where(Study.status == "queued", Study.created_at < cutoff)
                    .order_by(Study.id)
                )
            ]

    def start(
        self,
        study_id: int,
        batches: Sequence[range],
        *,
        plan: PlannedStage | None = None,
        exponent: float = 0.0,
    ) -> StageRecord | None:
        """queued -> running and open stage 0 (status planned) with pending ``batches``, in
        one transaction. Stage 0 normally has no plan: its points are
        ``initial_samples(prior, n_samples, seed)``, rows ``batch.chain_start:chain_stop``.
        Returns the stage, or None if the study was not queued (started only once)."""
        now = self.db.now()
        with self.db.write() as s:
            if not set_study_status(
                s, study_id, "running", now, from_=("queued",), started_at=now, current_stage=0
            ):
                if s.get(Study, study_id) is None:
                    raise NotFoundError(f"study {study_id} not found")
                return None
            append_event(s, study_id, "study_started", {"stage": 0}, now)
            stage = create_stage(s, study_id, 0, plan, batches, now, exponent=exponent)
            return stage_record(stage)

    def cancel(self, study_id: int, reason: str | None = None) -> bool:
        """queued/running -> cancelled. Leased work is abandoned: leases, heartbeats and
        results of a cancelled study are refused. False if the study had already ended."""
        now = self.db.now()
        with self.db.write() as s:
            if not set_study_status(s, study_id, "cancelled", now, error=reason):
                if s.get(Study, study_id) is None:
                    raise NotFoundError(f"study {study_id} not found")
                return False
            append_event(s, study_id, "study_cancelled", {"reason": reason}, now)
            return True

    def fail(self, study_id: int, error: str, payload: dict[str, Any] | None = None) -> bool:
        """queued/running -> failed with ``error`` (e.g. a reducer raised)."""
        now = self.db.now()
        with self.db.write() as s:
            if not fail_study(s, study_id, error, now, payload):
                if s.get(Study, study_id) is None:
                    raise NotFoundError(f"study {study_id} not found")
                return False
            return True
