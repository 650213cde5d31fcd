"""The TMCMC stage loop every driver runs: what stage 0 evaluates, and what a finished stage
leads to (paper section 2; Ching & Chen 2007).

A driver owns only how batches run and where stages are kept: :func:`~.tmcmc.run_tmcmc` maps
the batches in this process or a pool, the service leases them to workers and keeps the
stages in its database. Both go through :class:`Tempering`, so the stage-0 points (prior
draws or an earlier population, a repeated point run once), the stage transition (population
-> stopping rule -> next plan) and therefore the samples are the same bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.priors import JointPrior
from scm_core.inference.tmcmc.stage import (
    ChainBatchResult,
    LogLikelihoodBatch,
    PointEvaluation,
    StagePlan,
    StageState,
    TMCMCSettings,
    evaluate_points,
    first_occurrences,
    initial_samples,
    initial_state,
    plan_stage,
    reduce_stage,
    stage_status,
)

__all__ = ["PopulationStart", "StageStep", "Tempering", "ZeroRows", "evaluate_zero"]

#: a stage-0 batch: its points (m, d), the likelihood parts known there {k: (m, r_k)} and
#: which points repeat an earlier one (m,)
ZeroRows = tuple[NDArray[np.float64], dict[int, NDArray[np.float64]], NDArray[np.bool_]]


def evaluate_zero(rows: ZeroRows, log_likelihood_batch: LogLikelihoodBatch) -> PointEvaluation:
    """Stage 0 of one batch (:meth:`Tempering.stage_zero_rows`): its distinct new points run
    once (picklable: runs in a pool's or a worker's process)."""
    X, known, copies = rows
    return evaluate_points(X, log_likelihood_batch, known or None, copies)


@dataclass(frozen=True, eq=False)
class PopulationStart:
    """Stage 0 from an earlier posterior's population (n_samples, d) instead of prior draws: a
    posterior update, whose likelihood gives log b = log L(earlier data) (see
    :mod:`.stage`). ``tuning`` (beta, acceptance rate of that population's last stage)
    starts stage 1 with the proposal scale and step count adapted to it (see
    :func:`initial_state`); ``known_parts`` {part k: responses (n_samples, r_k)}: parts of a
    parted likelihood already simulated at those points (the old datasets), not run again."""

    samples: NDArray[np.float64]
    tuning: tuple[float, float] | None = None
    known_parts: Mapping[int, NDArray[np.float64]] | None = None


@dataclass(frozen=True, eq=False)
class StageStep:
    """A finished stage and what follows it: ``status`` None and the next stage's ``plan``,
    or the run's end ("completed", "stalled", "max_stages") and no plan."""

    state: StageState
    status: str | None
    plan: StagePlan | None


@dataclass(frozen=True, eq=False)
class Tempering:
    """The fixed inputs of one TMCMC run and its two steps.

    ``prior`` (d parameters), ``settings``, ``n_samples`` per stage, ``seed`` (every random
    number of the run derives from it and the stage index) and ``start`` (None: stage 0 draws
    from the prior; a :class:`PopulationStart`: an earlier posterior's population).
    """

    prior: JointPrior
    settings: TMCMCSettings
    n_samples: int
    seed: int
    start: PopulationStart | None = None

    def __post_init__(self) -> None:
        if int(self.seed) < 0:
            raise ValueError(f"'seed' must be a non-negative integer, got {self.seed!r}")

    @cached_property
    def points(self) -> NDArray[np.float64]:
        """Stage 0's points (n_samples, d): prior draws, or the start's population."""
        if self.start is None:
            return initial_samples(self.prior, self.n_samples, int(self.seed))
        X = np.array(self.start.samples, dtype=float)
        if X.shape != (self.n_samples, self.prior.dim):
            raise ValueError(
                f"the start population has shape {X.shape}, "
                f"expected ({self.n_samples}, {self.prior.dim})"
            )
        return X

    @cached_property
    def source(self) -> NDArray[np.int64]:
        """Each stage-0 point's first occurrence: an earlier population holds a state once per
        rejected move, and a repeated point is run once."""
        return first_occurrences(self.points)

    def stage_zero_rows(self, rows: range | slice) -> ZeroRows:
        """What the stage-0 batch of ``rows`` evaluates: its points, the likelihood parts
        already known there (the start's ``known_parts``) and which points repeat an earlier
        one (see :func:`evaluate_points`)."""
        r = slice(rows.start, rows.stop)
        known = self.start.known_parts if self.start is not None else None
        copies = self.source[r] != np.arange(r.start, r.stop)
        return self.points[r], {k: v[r] for k, v in (known or {}).items()}, copies

    def begin(self, evaluations: Sequence[PointEvaluation]) -> StageStep:
        """Stage 0's population from its batches' evaluations (in row order), and stage 1's
        plan."""
        tuning = self.start.tuning if self.start is not None else None
        state = initial_state(
            self.prior,
            self.points,
            evaluations,
            int(self.seed),
            self.settings,
            tuning,
            self.source,
        )
        return self.next(state)

    def advance(self, plan: StagePlan, results: Sequence[ChainBatchResult]) -> StageStep:
        """The population of the stage ``plan`` ran (its batches' results, in chain order),
        and what follows it."""
        return self.next(reduce_stage(plan, results))

    def next(self, state: StageState) -> StageStep:
        """What follows the finished stage ``state``: the stopping rule, else the next plan."""
        status = stage_status(state, self.settings)
        plan = plan_stage(state, self.prior, self.settings) if status is None else None
        return StageStep(state, status, plan)
