"""Stages kept in the database: a stored study's stage rows (plan blob, scalars, the
population's ``meta``) and sample rows, written by the exactly-once stage advance of
:mod:`services.store.repositories.stages`; and the stored forms that advance writes."""

from __future__ import annotations

import dataclasses
from functools import cached_property
from typing import Any

from scm_core.inference import StageState
from scm_core.inference._serial import encode_array
from scm_core.inference.tmcmc.stage import StagePlan
from services.exports.inference_data import StageRow
from services.store import PlannedStage, ReducedStage, SampleArrays, StageRecord, Store
from services.store.codec import encode, split

from .base import resolve_index

__all__ = ["DatabaseStages", "planned_stage", "reduced_stage", "stage_state"]

_ARRAYS = ("samples", "log_likelihood", "log_prior", "responses")

#: a stage's count of distinct samples, stored with its scalars (for the stage tables)
_UNIQUE = "unique_samples"


def planned_stage(plan: StagePlan) -> PlannedStage:
    """A TMCMC stage plan as the store keeps it (blob and diagnostics)."""
    return PlannedStage(
        stage=plan.stage,
        n_chains=plan.n_chains,
        blob=encode(plan),
        diagnostics={
            "exponent": plan.exponent,
            "prev_exponent": plan.prev_exponent,
            "beta": plan.prev_beta,
            "ess": plan.ess,
            "log_evidence_increment": plan.log_evidence_increment,
            "n_steps": int(plan.chain_length.max()) if plan.n_chains else 0,
        },
    )


def reduced_stage(state: StageState) -> ReducedStage:
    """A TMCMC stage's population as the store keeps it (``meta``: the state's scalars and its
    samples' Eves)."""
    meta, _ = split(state)
    meta["eve"] = encode_array(state.eve)
    return ReducedStage(
        stage=state.stage,
        population=SampleArrays(
            state.samples, state.log_likelihood, state.log_prior, state.responses
        ),
        model_runs=int(state.model_runs),
        failed_runs=int(state.failed_runs),
        diagnostics={
            "exponent": state.exponent,
            "acceptance": state.acceptance_rate,
            "ess": state.ess,
            "log_evidence": state.log_evidence,
            "n_steps": int(state.n_steps) if state.stage else None,
        },
        log_evidence_var=float(state.log_evidence_var),
        meta={
            **{k: v for k, v in meta.items() if k not in _ARRAYS},
            _UNIQUE: int(state.n_unique) if len(state.samples) else 0,
        },
    )


def stage_state(meta: dict[str, Any], population: SampleArrays) -> StageState:
    """The StageState of a done stage from the store's ``population(...)`` (bit-exact)."""
    scalars = {k: v for k, v in meta.items() if k != _UNIQUE}
    base = StageState.from_dict(dict(scalars, **dict.fromkeys(_ARRAYS)))
    return dataclasses.replace(
        base,
        samples=population.samples,
        log_likelihood=population.log_likelihood,
        log_prior=population.log_prior,
        responses=population.responses,
    )


class DatabaseStages:
    """The :class:`~services.stages.StageStore` of stored study ``study_id``: a view of its done
    stages as first read (one query), so that ``count``, ``state`` and ``rows`` agree while the
    study goes on; make a new one to see later stages."""

    def __init__(self, store: Store, study_id: int) -> None:
        self.store = store
        self.study_id = int(study_id)

    @cached_property
    def _done(self) -> list[StageRecord]:
        return [r for r in self.store.stages.list(self.study_id) if r.status == "done"]

    def count(self) -> int:
        return len(self._done)

    def state(self, index: int) -> StageState:
        i = resolve_index(index, self.count(), f"study {self.study_id}")
        return stage_state(*self.store.stages.population(self.study_id, i))

    def rows(self) -> list[StageRow]:
        return [StageRow.of(r.exponent, r.acceptance, r.log_evidence) for r in self._done]
