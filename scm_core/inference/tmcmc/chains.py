"""TMCMC's Metropolis chains of one stage (the per-batch unit of work): :func:`run_chains`, with
the exact accelerations of its moves (early rejection across datasets,
:mod:`scm_core.inference.early_rejection`; delayed acceptance with a response surrogate,
:mod:`scm_core.inference.surrogate`). See :mod:`scm_core.inference.tmcmc.stage` for the stage
as a whole."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from scm_core.inference import portable
from scm_core.inference.early_rejection import n_parts
from scm_core.inference.population_jump import JUMP_DOF
from scm_core.inference.surrogate import ResponseSurrogate, fit_surrogate, supports_surrogate
from scm_core.inference.tmcmc.evaluate import tempered
from scm_core.inference.tmcmc.moves import Move, move_of
from scm_core.inference.tmcmc.steps import (
    ChainNumbers,
    ChainState,
    MoveStrategy,
    PlainSteps,
    StepContext,
    SurrogateTransition,
)
from scm_core.inference.tmcmc.types import ChainBatchResult, LogLikelihoodBatch, StagePlan
from scm_core.inference.walk_space import log_columns

__all__ = ["chain_rng", "draw_numbers", "run_chains", "surrogate_floor"]

#: nats below the lowest tempered likelihood part of a stage's starting states at which the
#: surrogate target is floored where the surrogate gives no finite value
FLOOR_MARGIN = 10.0


def chain_rng(seed: int, stage: int, chain: int) -> np.random.Generator:
    """Random generator of one chain: SeedSequence(seed, spawn_key=(stage, chain))."""
    return np.random.Generator(
        np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(stage, chain)))
    )


def _surrogate_for(plan: StagePlan, f: LogLikelihoodBatch) -> ResponseSurrogate | None:
    """The delayed-acceptance surrogate of a stage (None: off, or too few training states),
    fitted on the plan's starting states and the states earlier stages evaluated, with their
    responses: a function of the plan alone."""
    settings = plan.settings
    if not (settings.delayed_acceptance and supports_surrogate(f)):
        return None
    samples, responses = plan.start_samples, plan.start_responses
    if plan.train_samples is not None and responses is not None:
        samples = np.concatenate([samples, plan.train_samples])
        responses = np.concatenate([responses, plan.train_responses])
    return fit_surrogate(
        samples,
        responses,
        tuple(f.response_inputs),
        settings.surrogate_neighbors,
        settings.surrogate_smoothing,
        getattr(f, "response_outputs", None),
    )


def surrogate_floor(plan: StagePlan) -> float:
    """The floor of the surrogate's tempered likelihood part (log b~ + exponent log L~) where
    the surrogate gives no finite value: the lowest finite value of the exact part over the
    stage's starting states, less :data:`FLOOR_MARGIN`. A constant of the plan, so pi~ is a
    fixed positive density wherever the prior is (the surrogate chain can reach every state
    the exact chain can)."""
    base = plan.start_log_prior - np.asarray(plan.prior.log_pdf(plan.start_samples), float)
    with np.errstate(invalid="ignore"):
        part = tempered(base, plan.start_log_likelihood, plan.exponent)
    finite = part[np.isfinite(part)]
    return float(finite.min() - FLOOR_MARGIN) if finite.size else 0.0


def run_chains(
    plan: StagePlan,
    chain_indices: Sequence[int] | NDArray[np.integer],
    log_likelihood_batch: LogLikelihoodBatch,
) -> ChainBatchResult:
    """Run the Metropolis chains ``chain_indices`` of ``plan`` (the per-batch unit of work).

    A chain makes ``chain_length`` moves. Without delayed acceptance a move is one Metropolis
    step: all still-active chains of the batch propose x' = x + L z (L L^T = proposal_cov)
    together; proposals inside the prior support are evaluated in one call of
    ``log_likelihood_batch`` and accepted with probability min(1, pi(x') / pi(x)),
    pi = prior * L^exponent. With delayed acceptance a move is a surrogate transition (Liu
    2001, section 9.4.3; Christen & Fox 2005 for one inner step): K = ``surrogate_steps``
    Metropolis steps on the surrogate target pi~ take x to y (no model run), then y is accepted
    with min(1, pi(y) pi~(x) / (pi(x) pi~(y))) after one model run, skipped when the inner
    steps did not move; K steps of a pi~-reversible kernel are pi~-reversible, so the move is
    pi-reversible whatever the surrogate's error (:mod:`scm_core.inference.surrogate`). With
    ``surrogate_jumps`` > 0 each inner step is, with that probability, a population jump
    instead of a walk step (:mod:`scm_core.inference.population_jump`). Where the surrogate
    cannot be fitted, a move is K plain steps. With early rejection a model run's parts run one
    by one (:mod:`scm_core.inference.early_rejection`). Each chain draws all its random numbers
    from :func:`chain_rng` (steps, acceptance numbers, then the inner steps' numbers, then the
    jumps' choices and chi-square variates), and every row operation is independent of the
    batch size, so the result of a chain is bit-identical however chains are batched. Pure
    apart from calling the likelihood; picklable via
    ``functools.partial(run_chains, plan, log_likelihood_batch=f)``
    when ``f`` is.
    """
    idx = np.asarray(chain_indices, dtype=np.int64).reshape(-1)
    if idx.size and (idx.min() < 0 or idx.max() >= plan.n_chains):
        raise ValueError(f"chain indices must lie in [0, {plan.n_chains})")
    if np.unique(idx).size != idx.size:
        raise ValueError("chain indices must be distinct")
    f = log_likelihood_batch
    settings = plan.settings
    lengths = plan.chain_length[idx]
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    sur = _surrogate_for(plan, f)
    K = int(settings.surrogate_steps) if settings.delayed_acceptance else 1
    jumps = sur is not None and settings.surrogate_jumps > 0.0 and plan.jump_chol is not None
    parts = n_parts(f)
    ctx = StepContext(
        plan=plan,
        f=f,
        numbers=draw_numbers(plan, idx, offsets, K, jumps),
        offsets=offsets,
        K=K,
        logs=log_columns(plan.prior, settings.proposal_scale),
        jumps=jumps,
        staged=settings.early_rejection and parts > 1,
        parts=parts,
    )
    state = ChainState(
        x=plan.start_samples[idx].copy(),
        ll=plan.start_log_likelihood[idx].copy(),
        lp=plan.start_log_prior[idx].copy(),
        resp=None if plan.start_responses is None else plan.start_responses[idx].copy(),
        keep_evaluated=settings.delayed_acceptance and plan.start_responses is not None,
    )
    strategy: MoveStrategy = (
        PlainSteps(count_inner=settings.delayed_acceptance)
        if sur is None
        else SurrogateTransition(sur, surrogate_floor(plan), ctx, state)
    )
    accepted = np.zeros(idx.size, dtype=np.int64)
    proposed = np.zeros(idx.size, dtype=np.int64)
    out = _Output(move_of(settings.moves), lengths, state)
    for t in range(int(lengths.max()) if idx.size else 0):
        active = np.flatnonzero(lengths > t)
        accepted[active] += strategy.move(ctx, state, active, t)
        proposed[active] += 1
        out.emit(state, active, t)
    return ChainBatchResult(
        stage=plan.stage,
        chain_indices=idx,
        **out.result(state),
        accepted=accepted,
        proposed=proposed,
        surrogate_error=state.error,
        **_evaluated(state, idx.size, plan.start_samples.shape[1]),
        **state.counters.counts().count_values(),
    )


def draw_numbers(
    plan: StagePlan, idx: NDArray[np.int64], offsets: NDArray[np.int64], K: int, jumps: bool
) -> ChainNumbers:
    """Every random number of the chains ``idx``, each chain's from :func:`chain_rng` in a
    fixed order: the normal variates, the acceptance numbers, with delayed acceptance the inner
    steps' numbers, then (with jumps) the jumps' choices and chi-square variates; so a chain's
    numbers do not depend on its batch, and a chain without jumps draws what it drew before
    jumps existed."""
    d = plan.start_samples.shape[1]
    settings = plan.settings
    total = int(offsets[-1]) * K
    Z = np.empty((total, d))
    log_u = np.empty(total)
    log_u1 = np.empty(total)
    jump_at = np.zeros(total, dtype=bool)
    chi2 = np.ones(total)
    for k, c in enumerate(idx):
        rng = chain_rng(plan.seed, plan.stage, int(c))
        a, b = offsets[k] * K, offsets[k + 1] * K
        Z[a:b] = rng.standard_normal((b - a, d))
        log_u[a:b] = portable.log(rng.random(b - a))
        if settings.delayed_acceptance:
            log_u1[a:b] = portable.log(rng.random(b - a))
        if jumps:
            jump_at[a:b] = rng.random(b - a) < settings.surrogate_jumps
            chi2[a:b] = rng.chisquare(JUMP_DOF, b - a)
    return ChainNumbers(Z, log_u, log_u1, jump_at, chi2)


class _Output:
    """The samples a batch's chains give: their final states, or (a move that keeps every
    step: leader, waste-free) every state after each move, and the start where kept."""

    def __init__(self, move: Move, lengths: NDArray[np.int64], state: ChainState) -> None:
        self.keep_all = move.keeps_every_step
        if not self.keep_all:
            return
        self.first = int(move.keeps_start)
        self.counts = (lengths + self.first).astype(np.int64)
        self.off = np.concatenate([[0], np.cumsum(self.counts)]).astype(np.int64)
        n_out, d = int(self.off[-1]), state.x.shape[1]
        self.x = np.empty((n_out, d))
        self.ll = np.empty(n_out)
        self.lp = np.empty(n_out)
        self.resp = None if state.resp is None else np.empty((n_out, state.resp.shape[1]))
        if self.first:
            self._put(state, np.arange(state.x.shape[0]), self.off[:-1])

    def _put(self, state: ChainState, active: NDArray[np.int64], rows: NDArray[np.int64]):
        self.x[rows] = state.x[active]
        self.ll[rows] = state.ll[active]
        self.lp[rows] = state.lp[active]
        if self.resp is not None:
            self.resp[rows] = state.resp[active]

    def emit(self, state: ChainState, active: NDArray[np.int64], t: int) -> None:
        """After move t of the chains ``active``."""
        if self.keep_all:
            self._put(state, active, self.off[active] + self.first + t)

    def result(self, state: ChainState) -> dict[str, object]:
        if self.keep_all:
            return {
                "output_counts": self.counts,
                "samples": self.x,
                "log_likelihood": self.ll,
                "log_prior": self.lp,
                "responses": self.resp,
            }
        return {
            "output_counts": np.ones(state.x.shape[0], dtype=np.int64),
            "samples": state.x,
            "log_likelihood": state.ll,
            "log_prior": state.lp,
            "responses": state.resp,
        }


def _evaluated(state: ChainState, c: int, d: int) -> dict[str, NDArray]:
    """The states the chains' model runs evaluated, chain by chain in step order (the
    surrogate's next training states), as ChainBatchResult fields; empty without delayed
    acceptance."""
    if not state.keep_evaluated:
        return {}
    pos = np.concatenate(state.ev_pos) if state.ev_pos else np.empty(0, dtype=np.int64)
    order = np.argsort(pos, kind="stable")
    k = state.resp.shape[1]
    return {
        "evaluated_counts": np.bincount(pos, minlength=c).astype(np.int64),
        "evaluated_samples": (np.concatenate(state.ev_x) if state.ev_x else np.empty((0, d)))[
            order
        ],
        "evaluated_responses": (np.concatenate(state.ev_r) if state.ev_r else np.empty((0, k)))[
            order
        ],
    }
