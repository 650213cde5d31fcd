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

from collections.abc import Sequence
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
from .studies import load_study, set_study_status

__all__ = ["StageRepository", "create_stage", "ready_stages", "stage_record"]

OPEN = ("planned", "running")
FINAL_STUDY = ("completed", "stalled", "failed")


def _opt(x: float | None) -> float | None:
    return None if x is None else float(x)


#: scalars of a done stage's stored state that its record exposes as ``counts``
STAGE_COUNTS = (
    "part_runs",
    "early_rejections",
    "part_runs_saved",
    "first_stage_rejections",
    "surrogate_checks",
    "inner_accepted",
    "inner_proposed",
    "jump_accepted",
    "jump_proposed",
    "unique_samples",
)


def stage_record(st: Stage) -> StageRecord:
    return StageRecord(
        id=st.id,
        study_id=st.study_id,
        stage_index=st.stage_index,
        status=st.status,
        exponent=st.exponent,
        prev_exponent=st.prev_exponent,
        beta=st.beta,
        acceptance=st.acceptance,
        ess=st.ess,
        log_evidence_increment=st.log_evidence_increment,
        log_evidence=st.log_evidence,
        n_chains=st.n_chains,
        n_steps=st.n_steps,
        n_batches=st.n_batches,
        model_runs=st.model_runs,
        failed_runs=st.failed_runs,
        created_at=st.created_at,
        updated_at=st.updated_at,
        finished_at=st.finished_at,
        counts={k: int(st.state_meta[k]) for k in STAGE_COUNTS if k in (st.state_meta or {})},
    )


def _check_batches(batches: Sequence[range], n_chains: int | None) -> int:
    """Batches must be consecutive, step-1, non-empty ranges from 0; returns the chain count."""
    if not batches:
        raise ValueError("a stage needs at least one work batch")
    pos = 0
    for i, r in enumerate(batches):
        if r.step != 1 or r.start != pos or r.stop <= r.start:
            raise ValueError(f"batch {i} {r} does not continue consecutively from chain {pos}")
        pos = r.stop
    if n_chains is not None and pos != n_chains:
        raise ValueError(f"batches cover {pos} chains, the plan has {n_chains}")
    return pos


def create_stage(
    session: Session,
    study_id: int,
    stage_index: int,
    plan: PlannedStage | None,
    batches: Sequence[range],
    now: datetime,
    *,
    exponent: float | None = None,
) -> Stage:
    """Insert stage ``stage_index`` (status planned) with its plan blob and pending batches."""
    n_chains = _check_batches(batches, None if plan is None else plan.n_chains)
    stage = Stage(
        study_id=study_id,
        stage_index=stage_index,
        status="planned",
        n_chains=n_chains,
        n_batches=len(batches),
        created_at=now,
        updated_at=now,
    )
    if plan is not None:
        if plan.stage != stage_index:
            raise ValueError(f"plan is for stage {plan.stage}, not {stage_index}")
        stage.plan = plan.blob
        stage.exponent = _opt(plan.exponent)
        stage.prev_exponent = _opt(plan.prev_exponent)
        stage.beta = _opt(plan.beta)
        stage.ess = _opt(plan.ess)
        stage.log_evidence_increment = _opt(plan.log_evidence_increment)
        stage.n_steps = plan.n_steps
    else:
        stage.exponent = exponent
    session.add(stage)
    session.flush()
    session.execute(
        sa.insert(WorkBatch),
        [
            {
                "study_id": study_id,
                "stage_index": stage_index,
                "batch_index": i,
                "chain_start": r.start,
                "chain_stop": r.stop,
                "status": "pending",
                "attempts": 0,
                "created_at": now,
            }
            for i, r in enumerate(batches)
        ],
    )
    append_event(
        session,
        study_id,
        "stage_planned",
        {
            "stage": stage_index,
            "exponent": stage.exponent,
            "n_chains": n_chains,
            "n_batches": len(batches),
        },
        now,
    )
    return stage


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
        if adv.next_plan is None and adv.final_status not in FINAL_STUDY:
            raise ValueError(
                f"with no next plan, final_status must be one of {FINAL_STUDY}, "
                f"got {adv.final_status!r}"
            )

        insert_samples(s, st.id, red.population)
        s.execute(
            sa.update(Stage)
            .where(Stage.id == st.id)
            .values(
                status="done",
                exponent=_opt(red.exponent),
                acceptance=_opt(red.acceptance),
                ess=_opt(red.ess),
                log_evidence=_opt(red.log_evidence),
                model_runs=int(red.model_runs),
                failed_runs=int(red.failed_runs),
                n_steps=red.n_steps,
                state_meta=dict(red.meta),
                updated_at=now,
                finished_at=now,
            )
            .execution_options(synchronize_session=False)
        )
        append_event(
            s,
            study_id,
            "stage_done",
            {
                "stage": stage_index,
                "exponent": _opt(red.exponent),
                "acceptance": _opt(red.acceptance),
                "ess": _opt(red.ess),
                "log_evidence": _opt(red.log_evidence),
                "model_runs": int(red.model_runs),
                "failed_runs": int(red.failed_runs),
                **dict(adv.payload or {}),
            },
            now,
        )
        counters = {
            "log_evidence": _opt(red.log_evidence),
            "log_evidence_var": _opt(red.log_evidence_var),
            "model_runs": Study.model_runs + int(red.model_runs),
            "failed_runs": Study.failed_runs + int(red.failed_runs),
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
        if not set_study_status(
            s, study_id, final, now, from_=("running",), error=adv.error, **counters
        ):
            raise _InactiveError
        append_event(
            s,
            study_id,
            f"study_{final}",
            {"stage": stage_index, "log_evidence": red.log_evidence, "error": adv.error},
            now,
        )
        return AdvanceOutcome("advanced", final, None)
