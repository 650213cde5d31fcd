"""Stages of a study: open a stage with its plan and work batches, advance it exactly once.

Stage status: planned (plan and batches stored, no batch leased yet) -> running (a batch was
leased) -> reducing (only inside the advance transaction) -> done (population stored).

Exactly-once advance (:meth:`StageRepository.advance`), in ONE transaction:

1. compare-and-set ``UPDATE stages SET status='reducing' WHERE id=:id AND status IN
   ('planned','running') AND <no batch of the stage is not done> AND <study running>``; a
   rowcount of 0 means someone else advanced it (or it is not ready): return without work.
   On PostgreSQL the UPDATE holds the stage's row lock until commit, so a concurrent caller
   blocks on it and then sees 'done'; on SQLite the transaction holds the database write lock
   (BEGIN IMMEDIATE).
2. call the study kind's reducer (pure: e.g. TMCMC's ``reduce_stage`` + ``plan_stage``) with
   the plan blob and the batch result blobs;
3. store the population, mark the stage done, update the study, open the next stage or end the
   study, append events; commit.

If the reducer raises or the process dies, the transaction rolls back and the stage is
'running' again with its results intact: no stuck 'reducing' state exists outside a
transaction.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from ..errors import InvalidStateError, NotFoundError
from ..models import Stage, Study, WorkBatch
from ..records import (
    AdvanceOutcome,
    PlannedStage,
    ReducedStage,
    ReduceInput,
    Reducer,
    SampleArrays,
    StageAdvance,
    StageRecord,
)
from .base import Database
from .events import append_event
from .samples import fetch_arrays, insert_samples
from .stage_rows import (
    column_values,
    create_done_stage,
    create_stage,
    optional_float,
    stage_record,
)
from .studies import load_study, set_study_status

__all__ = ["StageRepository", "ready_stages"]

OPEN = ("planned", "running")
FINAL_STUDY = ("completed", "stalled", "failed")


def _not_done_batches(study_id: Any, stage_index: Any) -> sa.Exists:
    return (
        sa.select(WorkBatch.id)
        .where(
            WorkBatch.study_id == study_id,
            WorkBatch.stage_index == stage_index,
            WorkBatch.status != "done",
        )
        .exists()
    )


def ready_stages(session: Session) -> list[tuple[int, int]]:
    """(study_id, stage_index) of open stages of running studies whose batches are all done."""
    q = (
        sa.select(Stage.study_id, Stage.stage_index)
        .join(Study, Study.id == Stage.study_id)
        .where(
            Study.status == "running",
            Stage.status.in_(OPEN),
            ~_not_done_batches(Stage.study_id, Stage.stage_index),
        )
        .order_by(Stage.study_id, Stage.stage_index)
    )
    return [(int(a), int(b)) for a, b in session.execute(q)]


def _check_tail(adv: StageAdvance) -> None:
    if adv.next_plan is None and adv.final_status not in FINAL_STUDY:
        raise ValueError(
            f"with no next plan, final_status must be one of {FINAL_STUDY}, "
            f"got {adv.final_status!r}"
        )


def _get(session: Session, study_id: int, stage_index: int) -> Stage:
    st = session.scalar(
        sa.select(Stage)
        .where(Stage.study_id == study_id, Stage.stage_index == stage_index)
        .execution_options(populate_existing=True)
    )
    if st is None:
        raise NotFoundError(f"stage {stage_index} of study {study_id} not found")
    return st


class _InactiveError(Exception):
    """Raised inside the advance transaction to roll it back."""


class StageRepository:
    def __init__(self, db: Database) -> None:
        self.db = db

    def get(self, study_id: int, stage_index: int) -> StageRecord:
        with self.db.read() as s:
            return stage_record(_get(s, study_id, stage_index))

    def list(self, study_id: int) -> list[StageRecord]:
        with self.db.read() as s:
            rows = s.scalars(
                sa.select(Stage).where(Stage.study_id == study_id).order_by(Stage.stage_index)
            )
            return [stage_record(r) for r in rows]

    def plan(self, study_id: int, stage_index: int) -> bytes | None:
        """The stage's plan blob (None for a stage stored without one, e.g. stage 0)."""
        with self.db.read() as s:
            row = s.execute(
                sa.select(Stage.plan).where(
                    Stage.study_id == study_id, Stage.stage_index == stage_index
                )
            ).first()
        if row is None:
            raise NotFoundError(f"stage {stage_index} of study {study_id} not found")
        return None if row.plan is None else bytes(row.plan)

    def population(self, study_id: int, stage_index: int) -> tuple[dict[str, Any], SampleArrays]:
        """(the kind's ``meta``, the population) of a done stage; arrays bit-exact."""
        with self.db.read() as s:
            st = _get(s, study_id, stage_index)
            if st.status != "done" or st.state_meta is None:
                raise InvalidStateError(
                    f"stage {stage_index} of study {study_id} is {st.status}, not done"
                )
            return dict(st.state_meta), fetch_arrays(s, st.id)

    def ready(self) -> list[tuple[int, int]]:
        """Stages that can be advanced now (all batches done, study running)."""
        with self.db.read() as s:
            return ready_stages(s)

    def advance(self, study_id: int, stage_index: int, reducer: Reducer) -> AdvanceOutcome:
        """Advance the stage exactly once (see module docstring). ``reducer(ReduceInput)``
        runs inside the transaction, only for the caller that won the compare-and-set; if it
        raises, nothing is written and the exception propagates."""
        now = self.db.now()
        try:
            with self.db.write() as s:
                st = _get(s, study_id, stage_index)
                won = s.execute(
                    sa.update(Stage)
                    .where(
                        Stage.id == st.id,
                        Stage.status.in_(OPEN),
                        ~_not_done_batches(study_id, stage_index),
                        sa.select(Study.id)
                        .where(Study.id == study_id, Study.status == "running")
                        .exists(),
                    )
                    .values(status="reducing", updated_at=now)
                    .execution_options(synchronize_session=False)
                ).rowcount
                if won != 1:
                    return self._why_not(s, study_id, stage_index)
                return self._reduce(s, study_id, stage_index, reducer, now)
        except _InactiveError:
            with self.db.read() as s:
                return AdvanceOutcome("inactive", load_study(s, study_id).status)

    def _why_not(self, s: Session, study_id: int, stage_index: int) -> AdvanceOutcome:
        study = load_study(s, study_id)
        st = _get(s, study_id, stage_index)
        if st.status not in OPEN:
            return AdvanceOutcome("already", study.status)
        if study.status != "running":
            return AdvanceOutcome("inactive", study.status)
        return AdvanceOutcome("not_ready", study.status)

    def _reduce(
        self, s: Session, study_id: int, stage_index: int, reducer: Reducer, now: datetime
    ) -> AdvanceOutcome:
        st = _get(s, study_id, stage_index)
        blobs = (
            s.execute(
                sa.select(WorkBatch.result)
                .where(WorkBatch.study_id == study_id, WorkBatch.stage_index == stage_index)
                .order_by(WorkBatch.batch_index)
            )
            .scalars()
            .all()
        )
        plan_blob = s.scalar(sa.select(Stage.plan).where(Stage.id == st.id))
        inp = ReduceInput(
            study=load_study(s, study_id),
            stage=stage_record(st),
            plan=None if plan_blob is None else bytes(plan_blob),
            results=[bytes(b) for b in blobs],
        )
        adv = reducer(inp)
        if not isinstance(adv, StageAdvance):
            raise TypeError(f"reducer returned {type(adv).__name__}, expected StageAdvance")
        red = adv.reduced
        if not isinstance(red, ReducedStage):
            raise TypeError(f"reducer returned {type(red).__name__}, expected ReducedStage")
        if red.stage != stage_index:
            raise ValueError(f"reducer returned the state of stage {red.stage}")
        _check_tail(adv)

        insert_samples(s, st.id, red.population)
        s.execute(
            sa.update(Stage)
            .where(Stage.id == st.id)
            .values(status="done", **_done_values(red, now))
            .execution_options(synchronize_session=False)
        )
        _stage_done_event(s, study_id, stage_index, red, adv.payload, now)
        return _follow(s, study_id, stage_index, red, adv, (red.model_runs, red.failed_runs), now)

    def adopt(
        self,
        study_id: int,
        stages: Sequence[tuple[PlannedStage | None, ReducedStage]],
        tail: StageAdvance,
    ) -> AdvanceOutcome:
        """Give a queued study the done stages 0..k of the same run kept elsewhere (a results
        folder's checkpoints, another store): each (the plan it ran, None for stage 0; its
        reduced population), then what follows stage k (``tail``: the next plan and its
        batches, or the end and the result; its ``reduced`` is not used), in one
        transaction, as if the stages had run and been advanced here. The caller vouches
        that the stages are this study's run (kind, case, seed, datasets); the reducers of
        the later stages then continue it bit for bit. InvalidStateError if the study is not
        queued (a study adopts stages once, before it starts)."""
        if not stages:
            raise ValueError("adopt needs at least one stage")
        _check_tail(tail)
        now = self.db.now()
        k = len(stages) - 1
        with self.db.write() as s:
            if not set_study_status(
                s, study_id, "running", now, from_=("queued",), started_at=now, current_stage=k
            ):
                load_study(s, study_id)  # NotFoundError for an unknown study
                raise InvalidStateError(f"study {study_id} is not queued: it cannot adopt stages")
            append_event(s, study_id, "study_started", {"stage": 0, "adopted": len(stages)}, now)
            for i, (plan, red) in enumerate(stages):
                if red.stage != i or (plan is not None and plan.stage != i):
                    raise ValueError(f"stage {i} of the adopted run is labelled {red.stage}")
                st = create_done_stage(s, study_id, plan, red.population.samples.shape[0], now)
                insert_samples(s, st.id, red.population)
                s.execute(
                    sa.update(Stage)
                    .where(Stage.id == st.id)
                    .values(**_done_values(red, now))
                    .execution_options(synchronize_session=False)
                )
                _stage_done_event(s, study_id, i, red, None, now)
            runs = sum(int(red.model_runs) for _, red in stages)
            failed = sum(int(red.failed_runs) for _, red in stages)
            return _follow(s, study_id, k, stages[-1][1], tail, (runs, failed), now)


def _scalars(red: ReducedStage) -> dict[str, Any]:
    """A done stage's diagnostics and run counts (its columns, and its "stage_done" event)."""
    return {
        **column_values(red.diagnostics, "done"),
        "model_runs": int(red.model_runs),
        "failed_runs": int(red.failed_runs),
    }


def _done_values(red: ReducedStage, now: datetime) -> dict[str, Any]:
    """A done stage's columns from its reduced population."""
    return {
        **_scalars(red),
        "state_meta": dict(red.meta),
        "updated_at": now,
        "finished_at": now,
    }


def _stage_done_event(
    s: Session,
    study_id: int,
    stage_index: int,
    red: ReducedStage,
    payload: Mapping[str, Any] | None,
    now: datetime,
) -> None:
    info = {"stage": stage_index, **_scalars(red), **dict(payload or {})}
    append_event(s, study_id, "stage_done", info, now)


def _follow(
    s: Session,
    study_id: int,
    stage_index: int,
    red: ReducedStage,
    adv: StageAdvance,
    runs: tuple[int, int],
    now: datetime,
) -> AdvanceOutcome:
    """After done stage ``stage_index`` (``red``; ``runs``: the model runs and failed runs
    to add to the study's): open the next stage of ``adv`` or end the study."""
    model_runs, failed_runs = runs
    counters = {
        "log_evidence": optional_float(red.diagnostics.get("log_evidence")),
        "log_evidence_var": optional_float(red.log_evidence_var),
        "model_runs": Study.model_runs + int(model_runs),
        "failed_runs": Study.failed_runs + int(failed_runs),
    }
    if adv.next_plan is not None:
        nxt = stage_index + 1
        if adv.next_plan.stage != nxt:
            raise ValueError(f"next plan is for stage {adv.next_plan.stage}, not {nxt}")
        if not set_study_status(
            s, study_id, "running", now, from_=("running",), current_stage=nxt, **counters
        ):
            raise _InactiveError
        create_stage(s, study_id, nxt, adv.next_plan, adv.next_batches, now)
        return AdvanceOutcome("advanced", "running", nxt)
    final = str(adv.final_status)
    if adv.result is not None:
        counters["result"] = dict(adv.result)
    ended = set_study_status(
        s, study_id, final, now, from_=("running",), error=adv.error, **counters
    )
    if not ended:
        raise _InactiveError
    append_event(
        s,
        study_id,
        f"study_{final}",
        {
            "stage": stage_index,
            "log_evidence": red.diagnostics.get("log_evidence"),
            "error": adv.error,
        },
        now,
    )
    return AdvanceOutcome("advanced", final, None)
