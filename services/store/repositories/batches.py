"""Work batches: leases, heartbeats, idempotent results and the reaper.

A batch is ``pending`` until a worker leases it (``leased``, attempts + 1, lease until now +
lease_seconds, extended by heartbeats), then ``done`` with its result, or ``failed`` when a
lease expires (or the worker gives it back) after ``max_attempts`` leases; that fails the
study. Leases and results are only granted while the study is running, so cancelling a study
stops its work at the next heartbeat.

Concurrency: leasing picks a candidate with ``SELECT ... FOR UPDATE SKIP LOCKED`` on PostgreSQL
(workers never wait on each other's candidates) and then grants it with a conditional UPDATE
(``WHERE status='pending' OR (status='leased' AND lease_expires_at < now)``); on SQLite the
write transaction (BEGIN IMMEDIATE) already serialises writers and the same conditional UPDATE
is the atomic step. Storing a result is ``UPDATE ... SET status='done' WHERE status IN
('pending','leased')``: exactly one delivery gets rowcount 1 ("stored"); later ones change
nothing ("duplicate"). Results are deterministic (seeded per chain), so a result delivered by
a worker whose lease had expired is as good as any and is accepted.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from datetime import datetime
from typing import Any, Literal

import sqlalchemy as sa
from sqlalchemy.orm import Session

from ..errors import NotFoundError
from ..models import BATCH_STATUSES, Stage, Study, WorkBatch
from ..records import (
    BatchKey,
    BatchLease,
    BatchOutput,
    BatchRecord,
    CompleteOutcome,
    ReapReport,
)
from .base import Database
from .events import append_event, touch_study
from .stages import ready_stages
from .studies import fail_study

__all__ = ["BatchRepository"]


def _study_running() -> sa.Exists:
    return (
        sa.select(Study.id)
        .where(Study.id == WorkBatch.study_id, Study.status == "running")
        .exists()
    )


def _leasable(now: datetime) -> sa.ColumnElement[bool]:
    return sa.or_(
        WorkBatch.status == "pending",
        sa.and_(WorkBatch.status == "leased", WorkBatch.lease_expires_at < now),
    )


def _held_by(owner: str) -> sa.ColumnElement[bool]:
    owner = owner.rstrip("/")
    return sa.or_(
        WorkBatch.worker_id == owner,
        WorkBatch.worker_id.startswith(owner + "/", autoescape=True),
    )


def _still_held(batch_id: Any, worker_id: Any, attempt: Any) -> list[sa.ColumnElement[bool]]:
    """The batch is leased by this holder in this attempt (its lease was not lost)."""
    return [
        WorkBatch.id == batch_id,
        WorkBatch.status == "leased",
        WorkBatch.worker_id == worker_id,
        WorkBatch.attempts == attempt,
    ]


def _key_where(key: BatchKey) -> list[sa.ColumnElement[bool]]:
    return [
        WorkBatch.study_id == key.study_id,
        WorkBatch.stage_index == key.stage_index,
        WorkBatch.batch_index == key.batch_index,
    ]


def _key(row: Any) -> BatchKey:
    return BatchKey(int(row.study_id), int(row.stage_index), int(row.batch_index))


def _record(b: WorkBatch) -> BatchRecord:
    return BatchRecord(
        id=b.id,
        key=_key(b),
        chain_start=b.chain_start,
        chain_stop=b.chain_stop,
        status=b.status,
        attempts=b.attempts,
        worker_id=b.worker_id,
        leased_at=b.leased_at,
        lease_expires_at=b.lease_expires_at,
        heartbeat_at=b.heartbeat_at,
        dispatched_at=b.dispatched_at,
        finished_at=b.finished_at,
        error=b.error,
        model_runs=b.model_runs,
    )


def _check_result(result: BatchOutput, key: BatchKey, start: int, stop: int) -> None:
    if not isinstance(result, BatchOutput):
        raise TypeError(f"batch result must be a BatchOutput, got {type(result).__name__}")
    if result.stage != key.stage_index:
        raise ValueError(f"result of stage {result.stage} for batch {key}")
    if (result.start, result.stop) != (start, stop):
        raise ValueError(
            f"result of chains {result.start}..{result.stop} for batch {key} "
            f"(chains {start}..{stop})"
        )


class BatchRepository:
    def __init__(self, db: Database) -> None:
        self.db = db

    # ---- reading -------------------------------------------------------------------------

    def get(self, key: BatchKey) -> BatchRecord:
        with self.db.read() as s:
            b = s.scalar(sa.select(WorkBatch).where(*_key_where(key)))
            if b is None:
                raise NotFoundError(f"batch {key} not found")
            return _record(b)

    def list(self, study_id: int, stage_index: int | None = None) -> list[BatchRecord]:
        q = sa.select(WorkBatch).where(WorkBatch.study_id == study_id)
        if stage_index is not None:
            q = q.where(WorkBatch.stage_index == stage_index)
        q = q.order_by(WorkBatch.stage_index, WorkBatch.batch_index)
        with self.db.read() as s:
            return [_record(b) for b in s.scalars(q)]

    def counts(self, study_id: int, stage_index: int) -> dict[str, int]:
        """Batches of a stage by status (every status present, zeros included)."""
        with self.db.read() as s:
            return self._counts(s, study_id, stage_index)

    def count_done(self, study_id: int, stage_index: int) -> int:
        return self.counts(study_id, stage_index)["done"]

    @staticmethod
    def _counts(s: Session, study_id: int, stage_index: int) -> dict[str, int]:
        out = dict.fromkeys(BATCH_STATUSES, 0)
        rows = s.execute(
            sa.select(WorkBatch.status, sa.func.count())
            .where(WorkBatch.study_id == study_id, WorkBatch.stage_index == stage_index)
            .group_by(WorkBatch.status)
        )
        for status, n in rows:
            out[status] = int(n)
        return out

    def worker_count(self, study_id: int, stage_index: int) -> int:
        """How many workers (distinct lease holders) ran the stage's done batches."""
        with self.db.read() as s:
            n = s.scalar(
                sa.select(sa.func.count(sa.distinct(WorkBatch.worker_id))).where(
                    WorkBatch.study_id == study_id,
                    WorkBatch.stage_index == stage_index,
                    WorkBatch.status == "done",
                )
            )
        return int(n or 0)

    def results(self, study_id: int, stage_index: int) -> list[bytes]:
        """Result blobs of the stage's done batches, in batch order."""
        with self.db.read() as s:
            blobs = s.scalars(
                sa.select(WorkBatch.result)
                .where(
                    WorkBatch.study_id == study_id,
                    WorkBatch.stage_index == stage_index,
                    WorkBatch.status == "done",
                )
                .order_by(WorkBatch.batch_index)
            ).all()
        return [bytes(b) for b in blobs]

    # ---- leases --------------------------------------------------------------------------

    def _grant(
        self, s: Session, where: list[Any], worker_id: str, now: datetime, seconds: float | None
    ) -> BatchLease | None:
        expires = now + self.db.lease_delta(seconds)
        row = s.execute(
            sa.update(WorkBatch)
            .where(
                *where,
                _leasable(now),
                WorkBatch.attempts < self.db.max_attempts,
                _study_running(),
            )
            .values(
                status="leased",
                attempts=WorkBatch.attempts + 1,
                worker_id=worker_id,
                leased_at=now,
                heartbeat_at=now,
                lease_expires_at=expires,
            )
            .returning(
                WorkBatch.id,
                WorkBatch.study_id,
                WorkBatch.stage_index,
                WorkBatch.batch_index,
                WorkBatch.chain_start,
                WorkBatch.chain_stop,
                WorkBatch.attempts,
            )
            .execution_options(synchronize_session=False)
        ).first()
        if row is None:
            return None
        key = _key(row)
        started = s.execute(
            sa.update(Stage)
            .where(
                Stage.study_id == key.study_id,
                Stage.stage_index == key.stage_index,
                Stage.status == "planned",
            )
            .values(status="running", updated_at=now)
            .execution_options(synchronize_session=False)
        ).rowcount
        if started:
            touch_study(s, key.study_id, now)
        if row.attempts > 1:
            append_event(
                s,
                key.study_id,
                "batch_retry",
                {
                    "stage": key.stage_index,
                    "batch": key.batch_index,
                    "attempt": int(row.attempts),
                    "worker_id": worker_id,
                },
                now,
            )
        return BatchLease(
            batch_id=int(row.id),
            key=key,
            chain_start=int(row.chain_start),
            chain_stop=int(row.chain_stop),
            worker_id=worker_id,
            attempt=int(row.attempts),
            expires_at=expires,
        )

    def lease(
        self, worker_id: str, *, study_id: int | None = None, lease_seconds: float | None = None
    ) -> BatchLease | None:
        """Lease the next pending (or lease-expired) batch of a running study, oldest study
        and stage first; None if there is none. Batches at the attempt cap are left to
        :meth:`reap`."""
        now = self.db.now()
        q = (
            sa.select(WorkBatch.id)
            .where(
                _leasable(now),
                WorkBatch.attempts < self.db.max_attempts,
                _study_running(),
            )
            .order_by(WorkBatch.study_id, WorkBatch.stage_index, WorkBatch.batch_index)
            .limit(1)
        )
        if study_id is not None:
            q = q.where(WorkBatch.study_id == study_id)
        if self.db.is_postgresql:
            q = q.with_for_update(skip_locked=True)
        with self.db.write() as s:
            batch_id = s.scalar(q)
            if batch_id is None:
                return None
            return self._grant(s, [WorkBatch.id == batch_id], worker_id, now, lease_seconds)

    def claim(
        self, key: BatchKey, worker_id: str, *, lease_seconds: float | None = None
    ) -> BatchLease | None:
        """Lease one given batch (a Celery task for it): None if it is done, failed, leased
        by a live lease, at the attempt cap, or its study is not running."""
        now = self.db.now()
        with self.db.write() as s:
            return self._grant(s, _key_where(key), worker_id, now, lease_seconds)

    def heartbeat(self, lease: BatchLease, *, lease_seconds: float | None = None) -> bool:
        """Extend a lease; False if it was lost (re-leased, finished, study not running):
        the worker should then stop working on the batch."""
        now = self.db.now()
        with self.db.write() as s:
            res = s.execute(
                sa.update(WorkBatch)
                .where(
                    *_still_held(lease.batch_id, lease.worker_id, lease.attempt),
                    _study_running(),
                )
                .values(heartbeat_at=now, lease_expires_at=now + self.db.lease_delta(lease_seconds))
                .execution_options(synchronize_session=False)
            )
            return res.rowcount == 1

    def release(self, lease: BatchLease, error: str) -> Literal["requeued", "failed", "lost"]:
        """Give a leased batch back after an error: pending again, or failed (and the study
        failed) if it has had ``max_attempts`` leases. "lost" if the lease was not held."""
        now = self.db.now()
        with self.db.write() as s:
            status = sa.case(
                (WorkBatch.attempts >= self.db.max_attempts, sa.literal("failed")),
                else_=sa.literal("pending"),
            )
            row = s.execute(
                sa.update(WorkBatch)
                .where(*_still_held(lease.batch_id, lease.worker_id, lease.attempt))
                .values(status=status, worker_id=None, lease_expires_at=None, error=error)
                .returning(WorkBatch.status)
                .execution_options(synchronize_session=False)
            ).first()
            if row is None:
                return "lost"
            k = lease.key
            info = {"stage": k.stage_index, "batch": k.batch_index, "attempt": lease.attempt}
            if row.status == "failed":
                append_event(s, k.study_id, "batch_failed", {**info, "error": error}, now)
                fail_study(
                    s,
                    k.study_id,
                    f"batch {k.batch_index} of stage {k.stage_index} failed after "
                    f"{lease.attempt} attempts: {error}",
                    now,
                    info,
                )
                return "failed"
            append_event(s, k.study_id, "batch_released", {**info, "error": error}, now)
            return "requeued"

    # ---- results -------------------------------------------------------------------------

    def complete(
        self,
        key: BatchKey,
        result: BatchOutput,
        event: Mapping[str, Any] | None = None,
    ) -> CompleteOutcome:
        """Store a batch result idempotently: the first delivery is "stored", any later one
        is a "duplicate" and changes nothing; "rejected" if the batch failed or the study is
        not running. ``event``: payload of a "batch_done" event appended in the same
        transaction when the result is stored (stage and batch added). Returns the stage's
        done/total batch counts after the call."""
        now = self.db.now()
        with self.db.write() as s:
            row = s.execute(
                sa.select(WorkBatch.id, WorkBatch.chain_start, WorkBatch.chain_stop).where(
                    *_key_where(key)
                )
            ).first()
            if row is None:
                raise NotFoundError(f"batch {key} not found")
            _check_result(result, key, row.chain_start, row.chain_stop)
            res = s.execute(
                sa.update(WorkBatch)
                .where(
                    WorkBatch.id == row.id,
                    WorkBatch.status.in_(("pending", "leased")),
                    _study_running(),
                )
                .values(
                    status="done",
                    result=result.blob,
                    model_runs=result.model_runs,
                    finished_at=now,
                    lease_expires_at=None,
                    error=None,
                )
                .execution_options(synchronize_session=False)
            )
            # Count under the stage's row lock: of several last results stored at once, each
            # transaction counts only after the previous one committed, so exactly one sees
            # the stage complete (READ COMMITTED alone would let each miss the others').
            # Lock order as everywhere: batch row, then stage row, then study row (the event).
            s.execute(
                sa.select(Stage.id)
                .where(Stage.study_id == key.study_id, Stage.stage_index == key.stage_index)
                .with_for_update()
            )
            if res.rowcount == 1:
                status: Literal["stored", "duplicate", "rejected"] = "stored"
                if event is not None:
                    info = {"stage": key.stage_index, "batch": key.batch_index, **event}
                    append_event(s, key.study_id, "batch_done", info, now)
                else:
                    touch_study(s, key.study_id, now)
            else:
                current = s.scalar(sa.select(WorkBatch.status).where(WorkBatch.id == row.id))
                status = "duplicate" if current == "done" else "rejected"
            counts = self._counts(s, key.study_id, key.stage_index)
        return CompleteOutcome(status, counts["done"], sum(counts.values()))

    # ---- dispatch and reaper -------------------------------------------------------------

    def _leased_rows(self, *where: sa.ColumnElement[bool]) -> sa.Select:
        q = (
            sa.select(
                WorkBatch.id,
                WorkBatch.study_id,
                WorkBatch.stage_index,
                WorkBatch.batch_index,
                WorkBatch.attempts,
                WorkBatch.worker_id,
            )
            .where(WorkBatch.status == "leased", *where, _study_running())
            .order_by(WorkBatch.study_id, WorkBatch.stage_index, WorkBatch.batch_index)
        )
        if self.db.is_postgresql:
            q = q.with_for_update(skip_locked=True)
        return q

    def _take_back(
        self,
        s: Session,
        row: Any,
        now: datetime,
        event: str,
        why: str,
        requeued: list[BatchKey],
        failed: list[BatchKey],
        failed_studies: list[int],
    ) -> None:
        """A lost lease (``row`` from :meth:`_leased_rows`): back to pending, or failed with its
        study at the attempt cap; appends to the lists."""
        key = _key(row)
        if key.study_id in failed_studies:
            return
        info = {
            "stage": key.stage_index,
            "batch": key.batch_index,
            "attempt": int(row.attempts),
            "worker_id": row.worker_id,
        }
        cap = row.attempts >= self.db.max_attempts
        res = s.execute(
            sa.update(WorkBatch)
            .where(*_still_held(row.id, row.worker_id, row.attempts))
            .values(
                status="failed" if cap else "pending",
                worker_id=None,
                lease_expires_at=None,
                error=f"{why} (attempt {row.attempts}, worker {row.worker_id})",
                **({} if cap else {"dispatched_at": now}),
            )
            .execution_options(synchronize_session=False)
        )
        if res.rowcount != 1:
            return
        if cap:
            failed.append(key)
            append_event(s, key.study_id, "batch_failed", info, now)
            error = (
                f"batch {key.batch_index} of stage {key.stage_index}: {why} "
                f"after {row.attempts} attempts (max_attempts {self.db.max_attempts})"
            )
            if fail_study(s, key.study_id, error, now, info):
                failed_studies.append(key.study_id)
        else:
            requeued.append(key)
            append_event(s, key.study_id, event, info, now)

    def reclaim(self, owner: str, *, keep: str | None = None) -> ReapReport:
        """Take back at once the live leases of workers known to be dead: those held by
        ``owner`` or below it (worker ids are paths: ``local/<host>/<server>/<pid>``), except
        those of ``keep`` (the live server's own). Pending again ("lease_reclaimed" event), or
        failed with the study at the attempt cap, as after an expired lease. The embedded
        server calls it for a pool process that died and, at its start, for the leases of the
        server before it on this machine."""
        if not owner.strip("/"):
            raise ValueError("owner must not be empty (it would reclaim every lease)")
        now = self.db.now()
        requeued: list[BatchKey] = []
        failed: list[BatchKey] = []
        failed_studies: list[int] = []
        where = [_held_by(owner)]
        if keep:
            where.append(~_held_by(keep))
        with self.db.write() as s:
            for row in s.execute(self._leased_rows(*where)).all():
                self._take_back(
                    s, row, now, "lease_reclaimed", "worker died", requeued, failed, failed_studies
                )
        return ReapReport(requeued, failed, failed_studies, sorted(requeued), [])

    def give_back(self, owner: str) -> list[BatchKey]:
        """Put back the leases held by ``owner`` or below it as if never granted: pending
        again, the attempt not counted ("lease_given_back" event). For a command that ran a
        study here and was stopped (Ctrl-C) or killed: its batches were interrupted, not
        failed, so stopping a run never brings a batch nearer the attempt cap. Only for an
        owner known to be gone (a results folder's lock is held by the caller); returns the
        batches put back."""
        if not owner.strip("/"):
            raise ValueError("owner must not be empty (it would give back every lease)")
        now = self.db.now()
        back: list[BatchKey] = []
        with self.db.write() as s:
            rows = s.execute(
                sa.update(WorkBatch)
                .where(WorkBatch.status == "leased", _held_by(owner), WorkBatch.attempts > 0)
                .values(
                    status="pending",
                    attempts=WorkBatch.attempts - 1,
                    worker_id=None,
                    lease_expires_at=None,
                )
                .returning(WorkBatch.study_id, WorkBatch.stage_index, WorkBatch.batch_index)
                .execution_options(synchronize_session=False)
            ).all()
            for row in rows:
                key = _key(row)
                back.append(key)
                info = {"stage": key.stage_index, "batch": key.batch_index}
                append_event(s, key.study_id, "lease_given_back", info, now)
        return sorted(back)

    def mark_dispatched(self, keys: Iterable[BatchKey]) -> None:
        """Record that tasks for these batches were sent to the broker (now)."""
        keys = list(keys)
        if not keys:
            return
        now = self.db.now()
        with self.db.write() as s:
            s.execute(
                sa.update(WorkBatch)
                .where(
                    sa.tuple_(WorkBatch.study_id, WorkBatch.stage_index, WorkBatch.batch_index).in_(
                        [(k.study_id, k.stage_index, k.batch_index) for k in keys]
                    )
                )
                .values(dispatched_at=now)
                .execution_options(synchronize_session=False)
            )

    def reap(self, *, redispatch_after: float | None = None) -> ReapReport:
        """One pass of the reaper (one transaction):

        * leases expired before now: back to pending (to re-dispatch), or, at the attempt
          cap, the batch fails and its study fails with a "batch_failed" / "study_failed"
          event;
        * pending batches of running studies neither dispatched nor leased for
          ``redispatch_after`` seconds (default: the lease time), e.g. because the broker lost
          the message: listed for re-dispatch;
        * stages ready to advance (all batches done) are listed too.

        Re-dispatching may deliver a batch twice; :meth:`claim` and :meth:`complete` make
        that harmless.
        """
        now = self.db.now()
        stale_cutoff = now - self.db.lease_delta(redispatch_after)
        requeued: list[BatchKey] = []
        failed: list[BatchKey] = []
        failed_studies: list[int] = []
        with self.db.write() as s:
            q = self._leased_rows(WorkBatch.lease_expires_at < now)
            for row in s.execute(q).all():
                self._take_back(
                    s, row, now, "lease_expired", "lease expired", requeued, failed, failed_studies
                )

            stale_q = (
                sa.select(
                    WorkBatch.id, WorkBatch.study_id, WorkBatch.stage_index, WorkBatch.batch_index
                )
                .where(
                    WorkBatch.status == "pending",
                    sa.func.coalesce(WorkBatch.dispatched_at, WorkBatch.created_at) < stale_cutoff,
                    _study_running(),
                )
                .order_by(WorkBatch.study_id, WorkBatch.stage_index, WorkBatch.batch_index)
            )
            if self.db.is_postgresql:
                stale_q = stale_q.with_for_update(skip_locked=True)
            stale = s.execute(stale_q).all()
            if stale:
                s.execute(
                    sa.update(WorkBatch)
                    .where(WorkBatch.id.in_([r.id for r in stale]))
                    .values(dispatched_at=now)
                    .execution_options(synchronize_session=False)
                )
            to_dispatch = sorted({*requeued, *(_key(r) for r in stale)})
            ready = ready_stages(s)
        return ReapReport(requeued, failed, failed_studies, to_dispatch, ready)
