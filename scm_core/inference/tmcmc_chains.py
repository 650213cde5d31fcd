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
from scm_core.inference.population_jump import JUMP_DOF, jump_log_density, jump_proposal
from scm_core.inference.surrogate import ResponseSurrogate, fit_surrogate, supports_surrogate
from scm_core.inference.tmcmc_eval import batch_output, tempered
from scm_core.inference.tmcmc_moves import move_of
from scm_core.inference.tmcmc_types import ChainBatchResult, LogLikelihoodBatch, StagePlan
from scm_core.inference.walk_space import (
    from_walk,
    log_columns,
    log_proposal_ratio,
    rows_times,
    to_walk,
)

__all__ = ["chain_rng", "run_chains", "surrogate_floor"]

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


def _surrogate_target(
    sur: ResponseSurrogate,
    f: LogLikelihoodBatch,
    X: NDArray[np.float64],
    log_prior: NDArray[np.float64],
    exponent: float,
    floor: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(log pi~ = log prior + (log b~ + exponent log L~, or ``floor`` where that is not
    finite), log L~) at X, from the surrogate's responses."""
    if X.shape[0] == 0:
        return np.empty(0), np.empty(0)
    ll, _, _, base = batch_output(f.from_responses(X, sur.predict(X)), X)
    with np.errstate(invalid="ignore"):
        part = tempered(np.zeros(X.shape[0]) if base is None else base, ll, exponent)
    return log_prior + np.where(np.isfinite(part), part, floor), ll


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
    prior = plan.prior
    d = plan.start_samples.shape[1]
    p = plan.exponent
    settings = plan.settings
    lengths = plan.chain_length[idx]
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    total = int(offsets[-1])
    sur = _surrogate_for(plan, f)
    K = int(settings.surrogate_steps) if settings.delayed_acceptance else 1

    jumps = sur is not None and settings.surrogate_jumps > 0.0 and plan.jump_chol is not None
    Z = np.empty((total * K, d))
    log_u = np.empty(total * K)
    log_u1 = np.empty(total * K)
    jump_at = np.zeros(total * K, dtype=bool)
    chi2 = np.ones(total * K)
    for k, c in enumerate(idx):
        rng = chain_rng(plan.seed, plan.stage, int(c))
        a, b = offsets[k] * K, offsets[k + 1] * K
        Z[a:b] = rng.standard_normal((b - a, d))
        with np.errstate(divide="ignore"):
            log_u[a:b] = np.log(rng.random(b - a))
            if settings.delayed_acceptance:
                log_u1[a:b] = np.log(rng.random(b - a))
        if jumps:  # drawn last: the other numbers are those of a chain without jumps
            jump_at[a:b] = rng.random(b - a) < settings.surrogate_jumps
            chi2[a:b] = rng.chisquare(JUMP_DOF, b - a)

    x = plan.start_samples[idx].copy()
    ll = plan.start_log_likelihood[idx].copy()
    lp = plan.start_log_prior[idx].copy()
    resp = None if plan.start_responses is None else plan.start_responses[idx].copy()
    accepted = np.zeros(idx.size, dtype=np.int64)
    proposed = np.zeros(idx.size, dtype=np.int64)
    n = dict.fromkeys(
        (
            "model_runs",
            "failed_runs",
            "out_of_support",
            "part_runs",
            "part_runs_saved",
            "early_rejections",
            "first_stage_rejections",
            "surrogate_checks",
            "inner_accepted",
            "inner_proposed",
            "jump_accepted",
            "jump_proposed",
        ),
        0,
    )
    error = np.zeros(idx.size)  # per chain: sum of |log L~ - log L| at its full evaluations
    # states the model evaluated (chain position, state, responses), in step order
    keep_evaluated = settings.delayed_acceptance and resp is not None
    ev_pos: list[NDArray[np.int64]] = []
    ev_x: list[NDArray[np.float64]] = []
    ev_r: list[NDArray[np.float64]] = []
    parts = n_parts(f)
    staged = settings.early_rejection and parts > 1
    if sur is not None:
        floor = surrogate_floor(plan)
        sur_x, _ = _surrogate_target(sur, f, x, np.asarray(prior.log_pdf(x), float), p, floor)

    logs = log_columns(prior, settings.proposal_scale)

    def propose(y: NDArray[np.float64], rows: NDArray[np.int64]):
        """(x', log prior at x' (-inf outside the support), inside, log q(x | x') -
        log q(x' | x)) for states y: a random-walk step in walk coordinates
        (:mod:`scm_core.inference.walk_space`)."""
        if logs.any():
            u = to_walk(y, logs)
            u_prop = u + rows_times(plan.proposal_chol, Z[rows])
            y_prop = from_walk(u_prop, logs)
            q_ratio = log_proposal_ratio(u_prop, u, logs)
        else:
            y_prop = y + rows_times(plan.proposal_chol, Z[rows])
            q_ratio = np.zeros(y.shape[0])
        if jumps:
            jump = jump_at[rows]
            if jump.any():
                # population jumps: an independence proposal from the t of the population
                u_old = to_walk(y[jump], logs)
                u_new = jump_proposal(
                    plan.jump_mean, plan.jump_chol, Z[rows[jump]], chi2[rows[jump]]
                )
                y_prop[jump] = from_walk(u_new, logs)
                q_ratio[jump] = (
                    jump_log_density(u_old, plan.jump_mean, plan.jump_inv)
                    - jump_log_density(u_new, plan.jump_mean, plan.jump_inv)
                    + log_proposal_ratio(u_new, u_old, logs)
                )
        lp_prop = np.asarray(prior.log_pdf(y_prop), dtype=float)
        ok = np.isfinite(lp_prop) & np.asarray(prior.in_support(y_prop))
        n["out_of_support"] += ok.size - int(np.count_nonzero(ok))
        return y_prop, np.where(ok, lp_prop, -np.inf), ok, q_ratio

    def model_step(
        active: NDArray[np.int64],
        x_prop: NDArray[np.float64],
        lp_prop: NDArray[np.float64],
        run: NDArray[np.bool_],
        log_un: NDArray[np.float64],
        gate: NDArray[np.float64],
        sur_ll: NDArray[np.float64] | None,
    ) -> NDArray[np.bool_]:
        """Run the model at x_prop[run] and accept with log u < log pi(x') - log pi(x) - gate
        (gate: the surrogate's log pi~(x') - log pi~(x), 0 for a plain step); the accepted
        chains move. Returns the accepted mask."""
        with np.errstate(invalid="ignore"):
            current = tempered(lp[active], ll[active], p)  # log pi(x)
        lp_prop = lp_prop.copy()
        ll_prop = np.full(active.size, -np.inf)
        resp_prop = None
        n_run = int(np.count_nonzero(run))
        if n_run:
            evaluated = run
            if staged:
                with np.errstate(invalid="ignore"):
                    threshold = (log_un + current + gate - lp_prop)[run]
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
            lp_prop[run & ~evaluated] = -np.inf
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
                    if keep_evaluated:
                        fin = np.all(np.isfinite(resp_ok), axis=1)
                        ev_pos.append(active[evaluated][fin])
                        ev_x.append(x_prop[evaluated][fin])
                        ev_r.append(resp_ok[fin])
                if sur_ll is not None:
                    diff = np.abs(ll_ok - sur_ll[evaluated])
                    fin = np.isfinite(diff)
                    n["surrogate_checks"] += int(np.count_nonzero(fin))
                    chains = active[evaluated][fin]
                    error[chains] = error[chains] + diff[fin]
        with np.errstate(invalid="ignore"):
            log_ratio = tempered(lp_prop, ll_prop, p) - current - gate
        acc = run & (log_un < log_ratio)
        moved = active[acc]
        x[moved] = x_prop[acc]
        ll[moved] = ll_prop[acc]
        lp[moved] = lp_prop[acc]
        if resp is not None and resp_prop is not None:
            resp[moved] = resp_prop[acc]
        return acc

    def plain_move(active: NDArray[np.int64], t: int) -> NDArray[np.bool_]:
        """K plain Metropolis steps (one without delayed acceptance): moved mask."""
        moved = np.zeros(active.size, dtype=bool)
        for j in range(K):
            rows = (offsets[active] + t) * K + j
            x_prop, lp_prop, ok, q_ratio = propose(x[active], rows)
            acc = model_step(active, x_prop, lp_prop, ok, log_u[rows], -q_ratio, None)
            moved |= acc
            if settings.delayed_acceptance:
                n["inner_proposed"] += active.size
                n["inner_accepted"] += int(np.count_nonzero(acc))
        return moved

    def surrogate_move(active: NDArray[np.int64], t: int) -> NDArray[np.bool_]:
        """K Metropolis steps on pi~ from x to y, then the model's correction: moved mask."""
        y = x[active].copy()
        lp_y = np.asarray(prior.log_pdf(y), dtype=float)
        sur_y = sur_x[active].copy()
        sur_ll = np.full(active.size, np.nan)
        for j in range(K):
            rows = (offsets[active] + t) * K + j
            y_prop, lp_prop, ok, q_ratio = propose(y, rows)
            s_prop = np.full(active.size, -np.inf)
            ll_tilde = np.full(active.size, np.nan)
            s_prop[ok], ll_tilde[ok] = _surrogate_target(sur, f, y_prop[ok], lp_prop[ok], p, floor)
            acc = ok & (log_u1[rows] < s_prop - sur_y + q_ratio)
            if jumps:
                n["jump_proposed"] += int(np.count_nonzero(jump_at[rows]))
                n["jump_accepted"] += int(np.count_nonzero(acc & jump_at[rows]))
            y[acc], lp_y[acc], sur_y[acc], sur_ll[acc] = (
                y_prop[acc],
                lp_prop[acc],
                s_prop[acc],
                ll_tilde[acc],
            )
            n["inner_proposed"] += active.size
            n["inner_accepted"] += int(np.count_nonzero(acc))
        run = np.any(y != x[active], axis=1)
        n["first_stage_rejections"] += active.size - int(np.count_nonzero(run))
        gate = np.where(run, sur_y - sur_x[active], 0.0)
        rows = (offsets[active] + t) * K
        acc = model_step(active, y, lp_y, run, log_u[rows], gate, sur_ll)
        sur_x[active[acc]] = sur_y[acc]
        return acc

    move = move_of(settings.moves)
    keep_all = move.keeps_every_step
    if keep_all:
        # every state after each move is a sample, and the start too where the move keeps it
        first = int(move.keeps_start)
        counts = (lengths + first).astype(np.int64)
        out_off = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        n_out = int(out_off[-1])
        out_x = np.empty((n_out, d))
        out_ll = np.empty(n_out)
        out_lp = np.empty(n_out)
        out_resp = None if resp is None else np.empty((n_out, resp.shape[1]))

        def emit(active: NDArray[np.int64], rows: NDArray[np.int64]) -> None:
            out_x[rows] = x[active]
            out_ll[rows] = ll[active]
            out_lp[rows] = lp[active]
            if out_resp is not None:
                out_resp[rows] = resp[active]

        if first:
            emit(np.arange(idx.size), out_off[:-1])

    n_max = int(lengths.max()) if idx.size else 0
    for t in range(n_max):
        active = np.flatnonzero(lengths > t)
        moved = surrogate_move(active, t) if sur is not None else plain_move(active, t)
        accepted[active] += moved
        proposed[active] += 1
        if keep_all:
            emit(active, out_off[active] + first + t)

    if keep_all:
        samples, log_l, log_p, responses = out_x, out_ll, out_lp, out_resp
    else:
        counts = np.ones(idx.size, dtype=np.int64)
        samples, log_l, log_p, responses = x, ll, lp, resp
    evaluated = {}
    if keep_evaluated:
        pos = np.concatenate(ev_pos) if ev_pos else np.empty(0, dtype=np.int64)
        order = np.argsort(pos, kind="stable")  # chain by chain, each in step order
        evaluated = {
            "evaluated_counts": np.bincount(pos, minlength=idx.size).astype(np.int64),
            "evaluated_samples": (np.concatenate(ev_x) if ev_x else np.empty((0, d)))[order],
            "evaluated_responses": (np.concatenate(ev_r) if ev_r else np.empty((0, resp.shape[1])))[
                order
            ],
        }
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
        **evaluated,
        **n,
    )
