"""TMCMC's Metropolis chains of one stage (the per-batch unit of work): :func:`run_chains`, with
the exact accelerations of its moves (early rejection across datasets,
:mod:`scm_core.inference.early_rejection`; delayed acceptance with a response surrogate,
:mod:`scm_core.inference.surrogate`). See :mod:`scm_core.inference.tmcmc_stage` for the stage
as a whole."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.early_rejection import evaluate_staged, n_parts
from scm_core.inference.surrogate import ResponseSurrogate, fit_surrogate, supports_surrogate
from scm_core.inference.tmcmc_eval import batch_output, tempered
from scm_core.inference.tmcmc_moves import move_of
from scm_core.inference.tmcmc_types import ChainBatchResult, LogLikelihoodBatch, StagePlan

__all__ = ["chain_rng", "run_chains"]


def chain_rng(seed: int, stage: int, chain: int) -> np.random.Generator:
    """Random generator of one chain: SeedSequence(seed, spawn_key=(stage, chain))."""
    return np.random.Generator(
        np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(stage, chain)))
    )


def _apply_factor(chol: NDArray[np.float64], Z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows of Z @ chol.T by explicit column accumulation (row results independent of len(Z))."""
    out = np.zeros_like(Z)
    for j in range(Z.shape[1]):
        out = out + Z[:, j : j + 1] * chol[:, j]
    return out


def _surrogate_for(plan: StagePlan, f: LogLikelihoodBatch) -> ResponseSurrogate | None:
    """The delayed-acceptance surrogate of a stage (None: off, or too few training states),
    fitted on the plan's starting states and their responses only."""
    settings = plan.settings
    if not (settings.delayed_acceptance and supports_surrogate(f)):
        return None
    return fit_surrogate(
        plan.start_samples,
        plan.start_responses,
        tuple(f.response_inputs),
        settings.surrogate_neighbors,
        settings.surrogate_smoothing,
    )


def _surrogate_target(
    sur: ResponseSurrogate,
    f: LogLikelihoodBatch,
    X: NDArray[np.float64],
    log_prior: NDArray[np.float64],
    exponent: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(log pi~ = log prior + log b~ + exponent log L~, log L~) at X from the surrogate's
    responses; -inf where they give no finite value."""
    if X.shape[0] == 0:
        return np.empty(0), np.empty(0)
    ll, _, _, base = batch_output(f.from_responses(X, sur.predict(X)), X)
    lp = log_prior if base is None else log_prior + base
    with np.errstate(invalid="ignore"):
        target = tempered(lp, ll, exponent)
    return np.where(np.isfinite(target), target, -np.inf), ll


def run_chains(
    plan: StagePlan,
    chain_indices: Sequence[int] | NDArray[np.integer],
    log_likelihood_batch: LogLikelihoodBatch,
) -> ChainBatchResult:
    """Run the Metropolis chains ``chain_indices`` of ``plan`` (the per-batch unit of work).

    At every step all still-active chains of the batch propose x' = x + L z (L L^T =
    proposal_cov) together; proposals inside the prior support are evaluated in one call of
    ``log_likelihood_batch`` and accepted with probability min(1, pi(x') / pi(x)), pi = prior *
    L^exponent. With delayed acceptance a proposal first passes the surrogate's screen
    min(1, pi~(x') / pi~(x)) and is then accepted with min(1, pi(x') pi~(x) / (pi(x) pi~(x')))
    (:mod:`scm_core.inference.surrogate`); with early rejection its parts run one by one
    (:mod:`scm_core.inference.early_rejection`). Each chain draws all its random numbers from
    :func:`chain_rng` (steps, acceptance numbers, then the screen's numbers), and every row
    operation is independent of the batch size, so the result of a chain is bit-identical
    however chains are batched. Pure apart from calling the likelihood; picklable via
    ``functools.partial(run_chains, plan, log_likelihood_batch=f)`` when ``f`` is.
    """
    idx = np.asarray(chain_indices, dtype=np.int64).reshape(-1)
    if idx.size and (idx.min() < 0 or idx.max() >= plan.n_chains):
        raise ValueError(f"chain indices must lie in [0, {plan.n_chains})")
    if np.unique(idx).size != idx.size:
        raise ValueError("chain indices must be distinct")
    f = log_likelihood_batch
    prior = plan.prior
    d = plan.start_samples.shape[1]
    p = plan.exponent
    lengths = plan.chain_length[idx]
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    total = int(offsets[-1])
    sur = _surrogate_for(plan, f)

    Z = np.empty((total, d))
    log_u = np.empty(total)
    log_u1 = np.empty(total)
    for k, c in enumerate(idx):
        rng = chain_rng(plan.seed, plan.stage, int(c))
        a, b = offsets[k], offsets[k + 1]
        Z[a:b] = rng.standard_normal((b - a, d))
        with np.errstate(divide="ignore"):
            log_u[a:b] = np.log(rng.random(b - a))
            if sur is not None:
                log_u1[a:b] = np.log(rng.random(b - a))

    x = plan.start_samples[idx].copy()
    ll = plan.start_log_likelihood[idx].copy()
    lp = plan.start_log_prior[idx].copy()
    resp = None if plan.start_responses is None else plan.start_responses[idx].copy()
    accepted = np.zeros(idx.size, dtype=np.int64)
    proposed = np.zeros(idx.size, dtype=np.int64)
    n = {
        "model_runs": 0,
        "failed_runs": 0,
        "out_of_support": 0,
        "part_runs": 0,
        "part_runs_saved": 0,
        "early_rejections": 0,
        "first_stage_rejections": 0,
        "surrogate_checks": 0,
    }
    error = np.zeros(idx.size)  # per chain: sum of |log L~ - log L| at its full evaluations
    parts = n_parts(f)
    staged = plan.settings.early_rejection and parts > 1
    if sur is not None:
        # log pi~ of the current states; prior part: the prior alone (lp may hold log b)
        sur_x, _ = _surrogate_target(sur, f, x, np.asarray(prior.log_pdf(x), float), p)

    leader = move_of(plan.settings.moves).keeps_every_step
    if leader:
        out_x = np.empty((total, d))
        out_ll = np.empty(total)
        out_lp = np.empty(total)
        out_resp = None if resp is None else np.empty((total, resp.shape[1]))

    n_max = int(lengths.max()) if idx.size else 0
    for t in range(n_max):
        active = np.flatnonzero(lengths > t)
        rows = offsets[active] + t
        x_prop = x[active] + _apply_factor(plan.proposal_chol, Z[rows])
        lp_prop = np.asarray(prior.log_pdf(x_prop), dtype=float)
        ok = np.isfinite(lp_prop) & np.asarray(prior.in_support(x_prop))
        n["out_of_support"] += active.size - int(np.count_nonzero(ok))
        with np.errstate(invalid="ignore"):
            current = tempered(lp[active], ll[active], p)  # log pi(x)
        # delayed acceptance: the screen; gate = log pi~(x') - log pi~(x) (0 when skipped: a
        # pair where either surrogate value is not finite takes a plain Metropolis step, a
        # condition symmetric in x and x', so the kernel stays reversible)
        gate = np.zeros(active.size)
        run = ok
        if sur is not None:
            sur_prop = np.full(active.size, -np.inf)
            sur_ll = np.full(active.size, np.nan)
            sur_prop[ok], sur_ll[ok] = _surrogate_target(sur, f, x_prop[ok], lp_prop[ok], p)
            screened = ok & np.isfinite(sur_prop) & np.isfinite(sur_x[active])
            gate[screened] = sur_prop[screened] - sur_x[active][screened]
            run = ok & ~(screened & ~(log_u1[rows] < gate))
            n["first_stage_rejections"] += int(np.count_nonzero(ok & ~run))
        ll_prop = np.full(active.size, -np.inf)
        resp_prop = None
        n_run = int(np.count_nonzero(run))
        if n_run:
            evaluated = run
            if staged:
                with np.errstate(invalid="ignore"):
                    threshold = (log_u[rows] + current + gate - lp_prop)[run]
                ev = evaluate_staged(f, x_prop[run], threshold, p)
                evaluated = run.copy()
                evaluated[run] = ev.complete
                n["part_runs"] += ev.part_runs
                n["part_runs_saved"] += ev.part_runs_saved
                n["early_rejections"] += int(np.count_nonzero(ev.rejected))
                n["failed_runs"] += ev.failed_rejected
                out = ev.output
            else:
                out = f(x_prop[run])
                n["part_runs"] += n_run * parts
            n["model_runs"] += n_run
            lp_prop[ok & ~evaluated] = -np.inf
            if out is not None:
                ll_ok, resp_ok, n_failed, base_ok = batch_output(out, x_prop[evaluated])
                ll_prop[evaluated] = ll_ok
                if base_ok is not None:
                    lp_prop[evaluated] = lp_prop[evaluated] + base_ok
                n["failed_runs"] += n_failed
                if resp is not None:
                    if resp_ok is None or resp_ok.shape[1] != resp.shape[1]:
                        raise ValueError(
                            "log_likelihood_batch must return the same responses shape"
                        )
                    resp_prop = np.full((active.size, resp.shape[1]), np.nan)
                    resp_prop[evaluated] = resp_ok
                if sur is not None:
                    diff = np.abs(ll_ok - sur_ll[evaluated])
                    fin = np.isfinite(diff)
                    n["surrogate_checks"] += int(np.count_nonzero(fin))
                    chains = active[evaluated][fin]
                    error[chains] = error[chains] + diff[fin]
        with np.errstate(invalid="ignore"):
            log_ratio = tempered(lp_prop, ll_prop, p) - current - gate
        acc = run & (log_u[rows] < log_ratio)
        moved = active[acc]
        x[moved] = x_prop[acc]
        ll[moved] = ll_prop[acc]
        lp[moved] = lp_prop[acc]
        if sur is not None:
            sur_x[moved] = sur_prop[acc]
        if resp is not None and resp_prop is not None:
            resp[moved] = resp_prop[acc]
        accepted[active] += acc
        proposed[active] += 1
        if leader:
            out_x[rows] = x[active]
            out_ll[rows] = ll[active]
            out_lp[rows] = lp[active]
            if out_resp is not None:
                out_resp[rows] = resp[active]

    if leader:
        counts = lengths.astype(np.int64)
        samples, log_l, log_p, responses = out_x, out_ll, out_lp, out_resp
    else:
        counts = np.ones(idx.size, dtype=np.int64)
        samples, log_l, log_p, responses = x, ll, lp, resp
    return ChainBatchResult(
        stage=plan.stage,
        chain_indices=idx,
        output_counts=counts,
        samples=samples,
        log_likelihood=log_l,
        log_prior=log_p,
        responses=responses,
        accepted=accepted,
        proposed=proposed,
        surrogate_error=error,
        **n,
    )
