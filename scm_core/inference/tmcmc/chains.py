"""TMCMC's Metropolis chains of one stage (the per-batch unit of work): :func:`run_chains`, with
the exact accelerations of its moves (early rejection across datasets, delayed acceptance with
a response surrogate, population jumps) as the strategies
:func:`~scm_core.inference.tmcmc.accelerations.accelerations_of` chooses from the settings.
See :mod:`scm_core.inference.tmcmc.stage` for the stage as a whole."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from scm_core.inference import portable
from scm_core.inference.tmcmc.accelerations import Accelerations, Jumps, accelerations_of
from scm_core.inference.tmcmc.moves import Move, move_of
from scm_core.inference.tmcmc.steps import ChainNumbers, ChainState, StepContext
from scm_core.inference.tmcmc.types import ChainBatchResult, LogLikelihoodBatch, StagePlan
from scm_core.inference.walk_space import log_columns

__all__ = ["chain_rng", "draw_numbers", "run_chains"]


def chain_rng(seed: int, stage: int, chain: int) -> np.random.Generator:
    """Random generator of one chain: SeedSequence(seed, spawn_key=(stage, chain))."""
    return np.random.Generator(
        np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(stage, chain)))
    )


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
    acc = accelerations_of(settings)
    sur = acc.moves.surrogate(plan, f)
    jumps = acc.jumps.for_batch(plan, sur)
    ctx = StepContext(
        plan=plan,
        f=f,
        numbers=draw_numbers(plan, idx, offsets, acc, jumps),
        offsets=offsets,
        K=acc.moves.inner_steps,
        logs=log_columns(plan.prior, settings.proposal_scale),
        jumps=jumps,
        runs=acc.runs.for_likelihood(f),
    )
    state = ChainState(
        x=plan.start_samples[idx].copy(),
        ll=plan.start_log_likelihood[idx].copy(),
        lp=plan.start_log_prior[idx].copy(),
        resp=None if plan.start_responses is None else plan.start_responses[idx].copy(),
        keep_evaluated=acc.moves.keeps_evaluated(plan),
    )
    strategy = acc.moves.mover(sur, ctx, state)
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
    plan: StagePlan,
    idx: NDArray[np.int64],
    offsets: NDArray[np.int64],
    acc: Accelerations,
    jumps: Jumps,
) -> ChainNumbers:
    """Every random number of the chains ``idx``, each chain's from :func:`chain_rng` in a
    fixed order: the normal variates, the acceptance numbers, with delayed acceptance the inner
    steps' numbers (``acc.moves``), then (with the batch's ``jumps``) the jumps' choices and
    chi-square variates; so a chain's numbers do not depend on its batch, and a chain without
    jumps draws what it drew before jumps existed."""
    d = plan.start_samples.shape[1]
    K = acc.moves.inner_steps
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
        inner = acc.moves.draw(rng, b - a)
        if inner is not None:
            log_u1[a:b] = inner
        jumped = jumps.draw(rng, b - a)
        if jumped is not None:
            jump_at[a:b], chi2[a:b] = jumped
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
