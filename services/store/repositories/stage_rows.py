"""The rows of one stage: insert a stage with its plan and pending work batches
(:func:`create_stage`), read one back as a record (:func:`stage_record`). Shared by the study
repository (stage 0, when a study starts) and the stage repository (the stages after it)."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime

import sqlalchemy as sa
from sqlalchemy.orm import Session

from ..models import Stage, WorkBatch
from ..records import Diagnostics, PlannedStage, StageRecord, filled_by, stage_columns
from .events import append_event

__all__ = [
    "column_values",
    "create_done_stage",
    "create_stage",
    "optional_float",
    "stage_record",
]


def optional_float(x: float | None) -> float | None:
    """A stored float column's value: None stays None, anything else becomes a float."""
    return None if x is None else float(x)


def stage_record(st: Stage) -> StageRecord:
    """A stage row as a record: its keys, status, own columns and times, and ``meta``."""
    columns = {f.name: getattr(st, f.name) for f in stage_columns()}
    return StageRecord(
        id=st.id,
        study_id=st.study_id,
        stage_index=st.stage_index,
        status=st.status,
        **columns,
        created_at=st.created_at,
        updated_at=st.updated_at,
        finished_at=st.finished_at,
        meta=dict(st.state_meta or {}),
    )


def column_values(diagnostics: Diagnostics, message: str) -> dict[str, float | int | None]:
    """The columns ``message`` ("plan", "done") fills, from its diagnostics: floats for the
    "real" columns, ints for the others, None for those it does not give."""
    kinds = {f.name: f.metadata["column"] for f in stage_columns()}
    out: dict[str, float | int | None] = {}
    for name in filled_by(message):
        x = diagnostics.get(name)
        out[name] = None if x is None else (float(x) if kinds[name] == "real" else int(x))
    return out


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


def _with_plan(stage: Stage, plan: PlannedStage) -> None:
    stage.plan = plan.blob
    for name, value in column_values(plan.diagnostics, "plan").items():
        setattr(stage, name, value)


def create_done_stage(
    session: Session, study_id: int, plan: PlannedStage | None, n_chains: int, now: datetime
) -> Stage:
    """Insert a stage (status done) that ran elsewhere, with the plan it ran (None: stage 0)
    and no work batches; its population and done columns are the caller's to write."""
    stage = Stage(
        study_id=study_id,
        stage_index=0 if plan is None else plan.stage,
        status="done",
        n_chains=int(plan.n_chains if plan is not None else n_chains),
        n_batches=0,
        created_at=now,
        updated_at=now,
    )
    if plan is not None:
        _with_plan(stage, plan)
    session.add(stage)
    session.flush()
    return stage


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
        _with_plan(stage, plan)
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
