"""The interface of a run's stage storage and the functions over it."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from scm_core.inference import StageState
from services.exports.inference_data import RunPopulation, StageRow

__all__ = ["StageStore", "StageStoreError", "run_population", "stage_states"]


class StageStoreError(LookupError):
    """A stage that is not there or cannot be read (the message names it)."""


@runtime_checkable
class StageStore(Protocol):
    """The done stages of one TMCMC run, consecutive from stage 0."""

    def count(self) -> int:
        """How many stages are done (0: none yet)."""
        ...

    def state(self, index: int) -> StageState:
        """Done stage ``index`` (negative: from the last) exactly as it was reduced;
        :class:`StageStoreError` if it is not done or cannot be read."""
        ...

    def rows(self) -> list[StageRow]:
        """Every done stage's exponent, acceptance rate and log evidence so far."""
        ...


def resolve_index(index: int, count: int, where: str) -> int:
    """``index`` (negative: from the end) as a done stage's number; StageStoreError else."""
    i = index + count if index < 0 else index
    if not 0 <= i < count:
        raise StageStoreError(f"{where}: no finished stage {index} ({count} finished)")
    return i


def stage_states(stages: StageStore, count: int | None = None) -> list[StageState]:
    """The first ``count`` done stages (None: all) in order, e.g. to resume the run."""
    n = stages.count() if count is None else count
    return [stages.state(i) for i in range(n)]


def run_population(stages: StageStore) -> RunPopulation:
    """A run as the ArviZ export takes it: the last done stage's population, stage 0's
    samples as the prior and every stage's row; StageStoreError if no tempering stage (after
    stage 0) has finished."""
    if stages.count() < 2:
        raise StageStoreError("no tempering stage has finished yet")
    final, prior = stages.state(-1), stages.state(0)
    return RunPopulation(
        final.samples, final.log_likelihood, final.log_prior, prior.samples, stages.rows()
    )
