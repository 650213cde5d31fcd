"""Transitional MCMC (Ching & Chen 2007) as pure functions over an explicit stage state.

One stage j -> j+1 is three steps, each a pure function of its inputs:

1. :func:`plan_stage` (once, anywhere): next tempering exponent p_{j+1} from the coefficient of
   variation of the plausibility weights w_i = L(theta_i)^(p_{j+1} - p_j), evidence increment
   log mean(w) and its variance, resampling, proposal covariance beta^2 * Cov_w
   and the chains to run.
2. :func:`run_chains` (any batch of chains, anywhere, in any order, possibly twice): Metropolis
   chains targeting log prior + p_{j+1} log L. Chain c of stage j draws its random numbers from
   ``SeedSequence(seed, spawn_key=(j, c))``, so results do not depend on how chains are batched.
3. :func:`reduce_stage` (once): assemble the batch results in chain order into the next
   :class:`StageState`, adapt the proposal scale beta and accumulate the log evidence.

Stage 0 (prior draws, ``spawn_key=(0,)``) is built by :func:`initial_samples`,
:func:`evaluate_points` (per batch) and :func:`initial_state`, in
:mod:`scm_core.inference.tmcmc.stage0`. The data (settings, states, plans,
batch results) are in :mod:`scm_core.inference.tmcmc.types`, the move schemes in
:mod:`scm_core.inference.tmcmc.moves`, the chains (with early rejection and delayed acceptance)
in :mod:`scm_core.inference.tmcmc.chains`.
:func:`stage_status` says when to stop.

Model calls go through ``log_likelihood_batch(X)`` with X of shape (m, d) in the prior's parameter
order, returning log L (m,) or a tuple (log L (m,), responses (m, k)). NaN and +inf are treated
as failed runs (log L = -inf) and counted; they are never raised. Proposals outside the prior's
support are rejected without a model run.

A third element, log b (m,), makes the untempered part of the target prior x b instead of the
prior: the stages then temper from prior x b (exponent 0) to prior x b x L (exponent 1), and
``log_prior`` of states and results holds log prior + log b. A posterior update (paper section
5.3) uses it with b = L(earlier data) and stage 0 = the earlier posterior's population, so the
evidence it accumulates is the incremental one, Z(new | old) (see :func:`initial_state`).

Three move schemes (``TMCMCSettings.moves``):

* ``"resample-move"`` (the default of :class:`TMCMCSettings`; a study that names no moves runs
  ``"waste-free"``, :data:`~scm_core.inference.tmcmc.moves.STUDY_MOVES`): every resampled
  point starts a chain of ``n_steps`` Metropolis steps; the chain's final state is the new
  sample. ``n_steps`` is fixed or adapted so that a chain moves at least once with probability
  ``move_probability`` given the last acceptance rate.
* ``"leader"`` (the paper's form): each distinct resampled point leads one chain whose length is
  its multiplicity and every visited state is a new sample, i.e. at most one model run per sample
  and stage (out-of-support proposals are rejected without one). Cheap, but measurably biased on
  targets with exact answers (evidence off by ~0.5-1 nat at 2000 samples).
* ``"waste-free"`` (Dau & Chopin 2022): M = n / P resampled points each start a chain of P - 1
  moves and all P states of each chain, its start included, are samples: n - M model runs per
  stage, consistent for any P (:class:`~scm_core.inference.tmcmc.moves.WasteFreeMove`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.priors import JointPrior
from scm_core.inference.tmcmc.accelerations import accelerations_of
from scm_core.inference.tmcmc.chains import chain_rng, run_chains
from scm_core.inference.tmcmc.moves import MOVES, move_of, steps_for_acceptance
from scm_core.inference.tmcmc.stage0 import (
    evaluate_points,
    first_occurrences,
    initial_samples,
    initial_state,
    stage_rng,
)
from scm_core.inference.tmcmc.types import (
    ChainBatchResult,
    LogLikelihoodBatch,
    PointEvaluation,
    StageCounts,
    StagePlan,
    StageState,
    TMCMCSettings,
)
from scm_core.inference.tmcmc.weights import (
    RESAMPLERS,
    adapt_beta,
    genealogy_log_evidence_var,
    multinomial_resample,
    next_exponent,
    plausibility_weights,
    proposal_factor,
    systematic_resample,
    weighted_covariance,
)
from scm_core.inference.walk_space import log_columns, to_walk, walk_bounds

__all__ = [
    "MOVES",
    "ChainBatchResult",
    "LogLikelihoodBatch",
    "PointEvaluation",
    "StagePlan",
    "StageState",
    "TMCMCSettings",
    "adapt_beta",
    "chain_batches",
    "chain_rng",
    "evaluate_points",
    "first_occurrences",
    "initial_samples",
    "initial_state",
    "multinomial_resample",
    "next_exponent",
    "plan_stage",
    "plausibility_weights",
    "reduce_stage",
    "run_chains",
    "stage_status",
    "steps_for_acceptance",
    "systematic_resample",
    "weighted_covariance",
]


def chain_batches(n: int, batch_size: int | None) -> list[range]:
    """Split 0..n-1 into consecutive ranges of ``batch_size`` (None: one range)."""
    size = n if batch_size is None else int(batch_size)
    if size < 1:
        raise ValueError(f"'batch_size' must be >= 1 or None, got {batch_size!r}")
    return [range(start, min(start + size, n)) for start in range(0, n, size)]


def stage_status(state: StageState, settings: TMCMCSettings) -> str | None:
    """None while the run should continue, else "completed", "stalled" or "max_stages"."""
    if state.exponent >= 1.0:
        return "completed"
    if not np.isfinite(state.log_likelihood).any():
        return "stalled"
    if state.stall_count >= settings.stall_stages:
        return "stalled"
    if state.stage >= settings.max_stages:
        return "max_stages"
    return None


# --------------------------------------------------------------------------------------------
# one tempering stage: plan -> run chains (batched) -> reduce
# --------------------------------------------------------------------------------------------


def _chain_sizes(state: StageState, settings: TMCMCSettings) -> NDArray[np.int64] | None:
    """Sizes of the consecutive blocks of ``state``'s samples that one chain made (None: the
    samples are treated as independent draws: stage 0, resample-move, leader)."""
    if state.stage < 1:
        return None
    return move_of(settings.moves).chain_sizes(state.n_samples, state.n_chains, settings)


def _log_mean_weight_var(
    weights: NDArray[np.float64], chain_sizes: NDArray[np.int64] | None
) -> float:
    """Delta-method variance of log mean(w) from the normalised weights: sum w_i^2 - 1/n for
    independent samples; with samples in chains, the chains are the independent units
    (Dau & Chopin 2022, section 3.4): sum_m W_m^2 - 1/M with W_m a chain's weight."""
    if chain_sizes is None:
        return max(float(np.sum(weights * weights)) - 1.0 / weights.size, 0.0)
    starts = np.concatenate([[0], np.cumsum(chain_sizes)[:-1]])
    w_chain = np.add.reduceat(weights, starts)
    return max(float(np.sum(w_chain * w_chain)) - 1.0 / w_chain.size, 0.0)


def plan_stage(
    state: StageState, prior: JointPrior, settings: TMCMCSettings | None = None
) -> StagePlan:
    """Plan stage ``state.stage + 1``: exponent, weights, evidence increment, resampling, proposal.

    Evidence increment log S = log mean_i w_i (Ching & Chen 2007); its variance by the delta
    method, Var(log S) ~ Var(w) / (n mean(w)^2) = sum_i wn_i^2 - 1/n for normalised weights wn
    (waste-free chains are the independent units, see :func:`_log_mean_weight_var`). The sum
    of these terms (``log_evidence_var_stagewise``) is a lower bound: it leaves out the
    correlation that resampling and slowly mixing chains carry from one stage to the next
    (2-6 times too small in sd where chains make few moves, docs/calibration.md). The variance
    of log Z-hat reported is the genealogy estimate
    :func:`~scm_core.inference.tmcmc.weights.genealogy_log_evidence_var`, which counts it,
    guarded from below by the stage-wise sum: max(genealogy, sum). The guard catches the
    genealogy estimate's low draws where lineages have coalesced to a few Eves (its noise; it
    is negative where small against it): over 20 seeds of the quick case, whose chains mix well
    and whose two estimates are close, ln Z +- se covers the replicates' mean 0.70 of the time
    with the guard and 0.60 without; on the exact targets the two rules cover alike. A
    fixed-lag variant (Olsson & Douc 2019: Eves taken 3-5 stages back) covered no better there
    and would need more stored per sample. A state stored before Eves were kept gets its stored
    variance plus the increment's. Resampling (``settings.resampling``) draws with
    SeedSequence(seed, spawn_key=(stage,)).
    """
    settings = settings or TMCMCSettings()
    if state.dim != prior.dim:
        raise ValueError(f"state has {state.dim} parameters, prior has {prior.dim}")
    stage = state.stage + 1
    n = state.n_samples
    p_prev = float(state.exponent)
    p = next_exponent(state.log_likelihood, p_prev, settings.target_cov)
    weights, log_s = plausibility_weights(state.log_likelihood, p - p_prev)
    sum_w2 = float(np.sum(weights * weights))
    ess = 1.0 / sum_w2
    log_s_var = _log_mean_weight_var(weights, _chain_sizes(state, settings))

    move = move_of(settings.moves)
    draws = move.resample_size(n, settings)
    resample = RESAMPLERS[settings.resampling]
    parent = resample(weights, draws, stage_rng(state.seed, stage))
    prev_stagewise = float(state.log_evidence_var_stagewise)
    if math.isnan(prev_stagewise):  # a state stored before the stage-wise sum was kept
        prev_stagewise = float(state.log_evidence_var)
    stagewise = prev_stagewise + log_s_var
    log_z_var = float(state.log_evidence_var) + log_s_var
    if state.eve is not None:
        genealogy = genealogy_log_evidence_var(
            weights, state.eve, stage, n, max(draws, 2), settings.resampling
        )
        log_z_var = max(genealogy, stagewise)
    logs = log_columns(prior, settings.proposal_scale)
    walk = to_walk(state.samples, logs)
    pop_cov = weighted_covariance(walk, weights)
    cov, chol = proposal_factor(state.beta**2 * pop_cov, walk_bounds(prior.bounds, logs))
    acc = accelerations_of(settings)
    # the population jumps' t proposal: the weighted population in walk coordinates
    jump = acc.jumps.plan_fields(walk, weights, pop_cov, walk_bounds(prior.bounds, logs))

    chain_start, chain_length = move.chains(parent, n, state.acceptance_rate, settings)
    chain_start = chain_start.astype(np.int64)
    resp = state.responses
    train_x, train_r = acc.moves.training_start(state)
    return StagePlan(
        stage=stage,
        seed=state.seed,
        prior=prior,
        settings=settings,
        exponent=p,
        prev_exponent=p_prev,
        weights=weights,
        log_evidence_increment=log_s,
        log_evidence_increment_var=log_s_var,
        ess=ess,
        parent=parent,
        chain_start=chain_start,
        chain_length=chain_length.astype(np.int64),
        start_samples=state.samples[chain_start].copy(),
        start_log_likelihood=state.log_likelihood[chain_start].copy(),
        start_log_prior=state.log_prior[chain_start].copy(),
        start_responses=None if resp is None else resp[chain_start].copy(),
        start_eve=None if state.eve is None else state.eve[chain_start].copy(),
        log_evidence_var=log_z_var,
        log_evidence_var_stagewise=stagewise,
        proposal_cov=cov,
        proposal_chol=chol,
        prev_beta=float(state.beta),
        prev_log_evidence=float(state.log_evidence),
        prev_log_evidence_var=float(state.log_evidence_var),
        prev_stall_count=int(state.stall_count),
        n_samples=n,
        train_samples=train_x,
        train_responses=train_r,
        **jump,
    )


def _chain_ordered(results: Sequence[ChainBatchResult], name: str) -> NDArray[np.float64]:
    """A per-chain field of the batch results in chain order (zeros where absent)."""
    chains = np.concatenate([r.chain_indices for r in results]) if results else np.empty(0, int)
    values = [
        np.zeros(r.chain_indices.size) if getattr(r, name) is None else getattr(r, name)
        for r in results
    ]
    out = np.concatenate(values) if values else np.empty(0)
    return out[np.argsort(chains, kind="stable")]


def reduce_stage(plan: StagePlan, batch_results: Sequence[ChainBatchResult]) -> StageState:
    """Assemble batch results (any order) into the next :class:`StageState`.

    Rows are ordered by chain index, so the result does not depend on batch order or batch
    composition. Every chain of the plan must appear exactly once. Adapts beta with
    :func:`adapt_beta` and accumulates the log evidence and its variance.
    """
    results = [r for r in batch_results if r.chain_indices.size]
    for r in results:
        if r.stage != plan.stage:
            raise ValueError(f"batch result of stage {r.stage} given for stage {plan.stage}")
    chains = np.concatenate([r.chain_indices for r in results]) if results else np.empty(0, int)
    expected = np.arange(plan.n_chains)
    if chains.size != plan.n_chains or not np.array_equal(np.sort(chains), expected):
        raise ValueError(
            f"batch results must cover chains 0..{plan.n_chains - 1} exactly once "
            f"(got {chains.size} chain results)"
        )
    row_chain = np.concatenate([np.repeat(r.chain_indices, r.output_counts) for r in results])
    order = np.argsort(row_chain, kind="stable")

    def gather(name: str) -> NDArray[np.float64]:
        return np.concatenate([getattr(r, name) for r in results], axis=0)[order]

    samples = gather("samples")
    if samples.shape[0] != plan.n_samples:
        raise ValueError(f"stage produced {samples.shape[0]} samples, expected {plan.n_samples}")
    has_resp = [r.responses is not None for r in results]
    responses = gather("responses") if all(has_resp) else None

    accepted = int(sum(int(r.accepted.sum()) for r in results))
    proposed = int(sum(int(r.proposed.sum()) for r in results))
    acceptance = accepted / proposed if proposed else math.nan
    n = functools.reduce(StageCounts.plus, (r.counts() for r in results), StageCounts())
    # the proposal scale follows the random-walk steps it drives: a surrogate transition's
    # inner steps (less its population jumps) when there are any, else the moves themselves
    walk_proposed = n.surrogate_steps - n.population_jumps
    step_acceptance = (
        (n.surrogate_steps_accepted - n.population_jumps_accepted) / walk_proposed
        if walk_proposed
        else acceptance
    )
    stalled = (plan.exponent - plan.prev_exponent) < plan.settings.stall_tol
    return StageState(
        stage=plan.stage,
        exponent=float(plan.exponent),
        samples=samples,
        log_likelihood=gather("log_likelihood"),
        log_prior=gather("log_prior"),
        responses=responses,
        beta=adapt_beta(plan.prev_beta, step_acceptance, plan.settings),
        acceptance_rate=float(acceptance),
        log_evidence=plan.prev_log_evidence + plan.log_evidence_increment,
        log_evidence_var=(
            plan.prev_log_evidence_var + plan.log_evidence_increment_var
            if math.isnan(plan.log_evidence_var)
            else plan.log_evidence_var
        ),
        log_evidence_var_stagewise=float(plan.log_evidence_var_stagewise),
        proposals=proposed,
        accepted=accepted,
        n_chains=plan.n_chains,
        n_steps=int(plan.chain_length.max()),
        ess=float(plan.ess),
        stall_count=plan.prev_stall_count + 1 if stalled else 0,
        seed=plan.seed,
        surrogate_error_sum=float(np.sum(_chain_ordered(results, "surrogate_error"))),
        **n.count_values(),
        eve=None if plan.start_eve is None else plan.start_eve[row_chain[order]],
        **accelerations_of(plan.settings).moves.carried(plan, results),
    )
