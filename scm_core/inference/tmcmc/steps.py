"""One move of a batch of TMCMC chains, as small strategy objects (the manner of emcee's moves).

:class:`ChainState` holds the chains' current states and the batch's counters;
:class:`StepContext` what every move reads (the plan, the likelihood, the chains' random
numbers). A move strategy's ``move(ctx, state, active, t)`` makes move ``t`` of the chains
``active`` and returns which of them moved:

* :class:`PlainSteps`: K plain Metropolis steps (K = 1 without delayed acceptance), each a
  model run and the test min(1, pi(x') q(x | x') / (pi(x) q(x' | x)));
* :class:`SurrogateTransition`: K Metropolis steps on the surrogate target pi~ (no model run),
  then one model run and the correction min(1, pi(y) pi~(x) / (pi(x) pi~(y))) (Liu 2001,
  section 9.4.3; Christen & Fox 2005 for K = 1).

Both end in :func:`model_step`, the model run (its strategy, with or without early rejection
across the likelihood's parts, and the inner steps' population jumps are the context's:
:mod:`scm_core.inference.tmcmc.accelerations`). See :func:`scm_core.inference.tmcmc.chains.
run_chains` for the loop over moves and the reproducibility rules.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.surrogate import ResponseSurrogate
from scm_core.inference.tmcmc.evaluate import batch_output, tempered
from scm_core.inference.tmcmc.types import (
    Failures,
    LogLikelihoodBatch,
    StageCounts,
    StagePlan,
    count_fields,
)
from scm_core.inference.walk_space import from_walk, log_proposal_ratio, rows_times, to_walk

if TYPE_CHECKING:  # the accelerations build the moves of this module
    from scm_core.inference.tmcmc.accelerations import Jumps, ModelRuns

__all__ = [
    "ChainCounters",
    "ChainNumbers",
    "ChainState",
    "MoveStrategy",
    "PlainSteps",
    "StepContext",
    "SurrogateTransition",
    "model_step",
    "propose",
    "surrogate_target",
]


class ChainCounters:
    """A batch's counters as its moves run: :class:`~scm_core.inference.tmcmc.types.
    StageCounts`' fields, added to with :meth:`add` and :meth:`failed`, read out with
    :meth:`counts`."""

    def __init__(self) -> None:
        self._n = {name: 0 for name, _ in count_fields()}
        self._reasons = Failures()

    def add(self, **counts: int) -> None:
        """Add to the named counters (a name StageCounts lacks is an error)."""
        for name, k in counts.items():
            if name not in self._n:
                raise KeyError(f"no stage counter {name!r}")
            self._n[name] += int(k)

    def failed(self, reasons: NDArray[np.str_] | None) -> None:
        """Count the reasons of failed runs (one per run, "" for a run that did not fail)."""
        if reasons is not None:
            self._reasons = self._reasons + Failures.of(np.asarray(reasons).tolist())

    def counts(self) -> StageCounts:
        return StageCounts(**self._n, failed_by=self._reasons)


@dataclass(frozen=True)
class ChainNumbers:
    """Every random number of a batch's chains, drawn before the first move; row
    ``(offset[chain] + t) * K + j`` belongs to inner step j of move t of a chain. Z: the walk's
    normal variates (or a jump's); log_u: the acceptance numbers of the model's test; log_u1:
    those of the surrogate's inner steps; jump_at: the inner steps that are population jumps;
    chi2: the jumps' chi-square variates."""

    Z: NDArray[np.float64]
    log_u: NDArray[np.float64]
    log_u1: NDArray[np.float64]
    jump_at: NDArray[np.bool_]
    chi2: NDArray[np.float64]


@dataclass(frozen=True)
class StepContext:
    """What every move of a batch reads: the stage plan, the likelihood, the random numbers,
    each chain's first row in them (``offsets``), the inner steps per move K, the walk's log
    columns, the inner steps' jumps (:class:`~scm_core.inference.tmcmc.accelerations.Jumps`)
    and how the model runs (:class:`~scm_core.inference.tmcmc.accelerations.ModelRuns`: all
    parts at once, or part by part with early rejection)."""

    plan: StagePlan
    f: LogLikelihoodBatch
    numbers: ChainNumbers
    offsets: NDArray[np.int64]
    K: int
    logs: NDArray[np.bool_]
    jumps: Jumps
    runs: ModelRuns

    def rows(self, active: NDArray[np.int64], t: int, j: int) -> NDArray[np.int64]:
        """Rows of inner step j of move t of the chains ``active`` in :class:`ChainNumbers`."""
        return (self.offsets[active] + t) * self.K + j


@dataclass
class ChainState:
    """The current state of a batch's chains (row i: the batch's i-th chain): x, log L, log
    prior (+ log b), responses; per chain the sum of |log L~ - log L| over checked runs; the
    states the model evaluated (chain row, state, responses; kept with delayed acceptance for
    the surrogate's next training set); the batch's counters."""

    x: NDArray[np.float64]
    ll: NDArray[np.float64]
    lp: NDArray[np.float64]
    resp: NDArray[np.float64] | None
    keep_evaluated: bool
    error: NDArray[np.float64] = field(init=False)
    counters: ChainCounters = field(default_factory=ChainCounters)
    ev_pos: list[NDArray[np.int64]] = field(default_factory=list)
    ev_x: list[NDArray[np.float64]] = field(default_factory=list)
    ev_r: list[NDArray[np.float64]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.error = np.zeros(self.x.shape[0])


def propose(
    ctx: StepContext, state: ChainState, y: NDArray[np.float64], rows: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
    """(x', log prior at x' (-inf outside the support), inside, log q(x | x') - log q(x' | x))
    for states y: a random-walk step in walk coordinates (:mod:`scm_core.inference.walk_space`),
    or at the rows drawn as jumps an independence proposal from the population's t."""
    plan, num, logs = ctx.plan, ctx.numbers, ctx.logs
    if logs.any():
        u = to_walk(y, logs)
        u_prop = u + rows_times(plan.proposal_chol, num.Z[rows])
        y_prop = from_walk(u_prop, logs)
        q_ratio = log_proposal_ratio(u_prop, u, logs)
    else:
        y_prop = y + rows_times(plan.proposal_chol, num.Z[rows])
        q_ratio = np.zeros(y.shape[0])
    ctx.jumps.propose(ctx, y, rows, y_prop, q_ratio)
    lp_prop = np.asarray(plan.prior.log_pdf(y_prop), dtype=float)
    ok = np.isfinite(lp_prop) & np.asarray(plan.prior.in_support(y_prop))
    state.counters.add(out_of_support=ok.size - int(np.count_nonzero(ok)))
    return y_prop, np.where(ok, lp_prop, -np.inf), ok, q_ratio


def surrogate_target(
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
    ll, _, _, base, _ = batch_output(f.from_responses(X, sur.predict(X)), X)
    with np.errstate(invalid="ignore"):
        part = tempered(np.zeros(X.shape[0]) if base is None else base, ll, exponent)
    return log_prior + np.where(np.isfinite(part), part, floor), ll


def _record_run(
    state: ChainState,
    active: NDArray[np.int64],
    evaluated: NDArray[np.bool_],
    x_prop: NDArray[np.float64],
    resp_ok: NDArray[np.float64] | None,
) -> NDArray[np.float64] | None:
    """The proposals' responses (NaN where not evaluated), keeping the evaluated states for the
    surrogate's training set."""
    if state.resp is None:
        return None
    if resp_ok is None or resp_ok.shape[1] != state.resp.shape[1]:
        raise ValueError("log_likelihood_batch must return the same responses shape")
    resp_prop = np.full((active.size, state.resp.shape[1]), np.nan)
    resp_prop[evaluated] = resp_ok
    if state.keep_evaluated:
        fin = np.all(np.isfinite(resp_ok), axis=1)
        state.ev_pos.append(active[evaluated][fin])
        state.ev_x.append(x_prop[evaluated][fin])
        state.ev_r.append(resp_ok[fin])
    return resp_prop


def model_step(
    ctx: StepContext,
    state: ChainState,
    active: NDArray[np.int64],
    x_prop: NDArray[np.float64],
    lp_prop: NDArray[np.float64],
    run: NDArray[np.bool_],
    log_un: NDArray[np.float64],
    gate: NDArray[np.float64],
    sur_ll: NDArray[np.float64] | None,
) -> NDArray[np.bool_]:
    """Run the model at x_prop[run] and accept with log u < log pi(x') - log pi(x) - gate
    (gate: the surrogate's log pi~(x') - log pi~(x), or -log q ratio for a plain step); the
    accepted chains move. Returns the accepted mask."""
    p, n = ctx.plan.exponent, state.counters
    with np.errstate(invalid="ignore"):
        current = tempered(state.lp[active], state.ll[active], p)  # log pi(x)
    lp_prop = lp_prop.copy()
    ll_prop = np.full(active.size, -np.inf)
    resp_prop = None
    n_run = int(np.count_nonzero(run))
    if n_run:
        with np.errstate(invalid="ignore"):
            threshold = (log_un + current + gate - lp_prop)[run]
        out, complete = ctx.runs.run(ctx.f, x_prop[run], threshold, p, n)
        evaluated = run.copy()
        evaluated[run] = complete
        n.add(model_runs=n_run)
        lp_prop[run & ~evaluated] = -np.inf
        if out is not None:
            ll_ok, resp_ok, n_failed, base_ok, failure = batch_output(out, x_prop[evaluated])
            ll_prop[evaluated] = ll_ok
            if base_ok is not None:
                lp_prop[evaluated] = lp_prop[evaluated] + base_ok
            n.add(failed_runs=n_failed)
            ctx.runs.failed(n, failure)
            resp_prop = _record_run(state, active, evaluated, x_prop, resp_ok)
            if sur_ll is not None:
                diff = np.abs(ll_ok - sur_ll[evaluated])
                fin = np.isfinite(diff)
                n.add(surrogate_checks=int(np.count_nonzero(fin)))
                chains = active[evaluated][fin]
                state.error[chains] = state.error[chains] + diff[fin]
    with np.errstate(invalid="ignore"):
        log_ratio = tempered(lp_prop, ll_prop, p) - current - gate
    acc = run & (log_un < log_ratio)
    moved = active[acc]
    state.x[moved] = x_prop[acc]
    state.ll[moved] = ll_prop[acc]
    state.lp[moved] = lp_prop[acc]
    if state.resp is not None and resp_prop is not None:
        state.resp[moved] = resp_prop[acc]
    return acc


class MoveStrategy(Protocol):
    """Makes move ``t`` of the chains ``active``; returns which of them moved."""

    def move(
        self, ctx: StepContext, state: ChainState, active: NDArray[np.int64], t: int
    ) -> NDArray[np.bool_]: ...


class PlainSteps:
    """K plain Metropolis steps per move (one without delayed acceptance), each a model run;
    with delayed acceptance on but no surrogate, its steps count as inner steps."""

    def __init__(self, count_inner: bool) -> None:
        self.count_inner = count_inner

    def move(
        self, ctx: StepContext, state: ChainState, active: NDArray[np.int64], t: int
    ) -> NDArray[np.bool_]:
        moved = np.zeros(active.size, dtype=bool)
        for j in range(ctx.K):
            rows = ctx.rows(active, t, j)
            x_prop, lp_prop, ok, q_ratio = propose(ctx, state, state.x[active], rows)
            acc = model_step(
                ctx, state, active, x_prop, lp_prop, ok, ctx.numbers.log_u[rows], -q_ratio, None
            )
            moved |= acc
            if self.count_inner:
                state.counters.add(
                    surrogate_steps=active.size,
                    surrogate_steps_accepted=int(np.count_nonzero(acc)),
                )
        return moved


class SurrogateTransition:
    """K Metropolis steps on the surrogate target pi~ from x to y, then the model's correction.
    ``sur_x`` (c,): log pi~ at every chain's current state (kept up to date as chains move);
    ``floor``: pi~'s floor where the surrogate gives no finite value."""

    def __init__(
        self, sur: ResponseSurrogate, floor: float, ctx: StepContext, state: ChainState
    ) -> None:
        self.sur = sur
        self.floor = floor
        lp_x = np.asarray(ctx.plan.prior.log_pdf(state.x), float)
        self.sur_x, _ = surrogate_target(sur, ctx.f, state.x, lp_x, ctx.plan.exponent, floor)

    def move(
        self, ctx: StepContext, state: ChainState, active: NDArray[np.int64], t: int
    ) -> NDArray[np.bool_]:
        n, num, p = state.counters, ctx.numbers, ctx.plan.exponent
        y = state.x[active].copy()
        lp_y = np.asarray(ctx.plan.prior.log_pdf(y), dtype=float)
        sur_y = self.sur_x[active].copy()
        sur_ll = np.full(active.size, np.nan)
        for j in range(ctx.K):
            rows = ctx.rows(active, t, j)
            y_prop, lp_prop, ok, q_ratio = propose(ctx, state, y, rows)
            s_prop = np.full(active.size, -np.inf)
            ll_tilde = np.full(active.size, np.nan)
            s_prop[ok], ll_tilde[ok] = surrogate_target(
                self.sur, ctx.f, y_prop[ok], lp_prop[ok], p, self.floor
            )
            acc = ok & (num.log_u1[rows] < s_prop - sur_y + q_ratio)
            ctx.jumps.count(n, num, rows, acc)
            y[acc], lp_y[acc], sur_y[acc], sur_ll[acc] = (
                y_prop[acc],
                lp_prop[acc],
                s_prop[acc],
                ll_tilde[acc],
            )
            n.add(surrogate_steps=active.size, surrogate_steps_accepted=int(np.count_nonzero(acc)))
        run = np.any(y != state.x[active], axis=1)
        n.add(first_stage_rejections=active.size - int(np.count_nonzero(run)))
        gate = np.where(run, sur_y - self.sur_x[active], 0.0)
        rows = ctx.rows(active, t, 0)
        acc = model_step(ctx, state, active, y, lp_y, run, num.log_u[rows], gate, sur_ll)
        self.sur_x[active[acc]] = sur_y[acc]
        return acc
