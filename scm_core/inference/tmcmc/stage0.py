"""Stage 0 of Transitional MCMC: the starting population and its likelihood.

:func:`initial_samples` draws it from the prior (or a posterior update passes the earlier
posterior's population), :func:`evaluate_points` evaluates a batch of its points (any batching,
anywhere) and :func:`initial_state` assembles the :class:`StageState` the stages start from.
A point repeated in the population runs once (:func:`first_occurrences`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.inference.early_rejection import is_parted, n_parts
from scm_core.inference.priors import JointPrior
from scm_core.inference.tmcmc.evaluate import batch_output, call_batch
from scm_core.inference.tmcmc.types import (
    Failures,
    LogLikelihoodBatch,
    PointEvaluation,
    StageState,
    TMCMCSettings,
)

__all__ = [
    "evaluate_points",
    "first_occurrences",
    "initial_samples",
    "initial_state",
    "stage_rng",
]


def stage_rng(seed: int, stage: int) -> np.random.Generator:
    """The generator of stage ``stage``'s own draws: SeedSequence(seed, spawn_key=(stage,))."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(stage,))))


def initial_samples(prior: JointPrior, n_samples: int, seed: int) -> NDArray[np.float64]:
    """Stage-0 prior draws (n, d) from SeedSequence(seed, spawn_key=(0,))."""
    if n_samples < 2:
        raise ValueError(f"'n_samples' must be >= 2, got {n_samples!r}")
    return prior.sample(stage_rng(seed, 0), n_samples)


def first_occurrences(X: ArrayLike) -> NDArray[np.int64]:
    """For each row of X (n, d), the index of the first row bitwise equal to it.

    Stage-0 points repeat when they are an earlier population (a posterior update starts from
    the parent's final stage, where a rejected move keeps a state twice); the simulator is
    deterministic, so a repeated point is run once (:func:`evaluate_points` with ``copies``,
    :func:`initial_state` with ``source``), the same for any batching."""
    X = np.ascontiguousarray(X, dtype=float)
    seen: dict[bytes, int] = {}
    return np.fromiter(
        (seen.setdefault(row.tobytes(), i) for i, row in enumerate(X)), np.int64, X.shape[0]
    )


def evaluate_points(
    X: ArrayLike,
    log_likelihood_batch: LogLikelihoodBatch,
    known_parts: Mapping[int, NDArray[np.float64]] | None = None,
    copies: NDArray[np.bool_] | None = None,
) -> PointEvaluation:
    """Evaluate the batch likelihood at fixed points (m, d); non-finite values -> -inf, counted.

    ``known_parts`` {part k: its responses (m, r_k)}: parts of a parted likelihood (see
    :mod:`.early_rejection`) already simulated at these points, e.g. the old datasets of a
    posterior update at the earlier posterior's population; only the other parts run and the
    output is assembled from both, bit-identical to the full evaluation (a part's responses do
    not depend on the others). A known part with a non-finite response runs again.
    ``copies`` (m,) bool: rows whose point is evaluated at an earlier row of the population
    (see :func:`first_occurrences`); they are not run and hold NaN until :func:`initial_state`
    copies their values in."""
    X = np.asarray(X, dtype=float)
    m = X.shape[0]
    if copies is not None and np.any(copies):
        run = np.flatnonzero(~np.asarray(copies, dtype=bool))
        known = {k: v[run] for k, v in (known_parts or {}).items()}
        return _scatter(evaluate_points(X[run], log_likelihood_batch, known), run, m)
    if m == 0:
        return PointEvaluation(np.empty(0), None, 0, model_runs=0)
    f = log_likelihood_batch
    if not known_parts or not is_parted(f):
        ll, resp, n_failed, base, failure = call_batch(f, X)
        return PointEvaluation(
            ll,
            resp,
            n_failed,
            base,
            part_runs=m * n_parts(f),
            model_runs=m,
            failed_by=Failures.of([] if failure is None else failure.tolist()),
        )
    responses, runs = [], 0
    reasons = np.full(m, "", dtype=object)
    for k in range(n_parts(f)):
        r = known_parts.get(k)
        if r is None or r.shape[0] != m or not np.all(np.isfinite(r)):
            _, r, *why = f.run_part(X, k)
            if why:  # the first failed part's reason
                reasons = np.where(reasons == "", np.asarray(why[0], dtype=object), reasons)
            runs += m
        responses.append(np.asarray(r, dtype=float))
    ll, resp, n_failed, base, _ = batch_output(f.assemble(X, responses), X)
    reasons = np.where(np.isfinite(ll), "", reasons)
    return PointEvaluation(
        ll,
        resp,
        n_failed,
        base,
        part_runs=runs,
        model_runs=m,
        failed_by=Failures.of(reasons.tolist()),
    )


def _scatter(ev: PointEvaluation, rows: NDArray[np.int64], m: int) -> PointEvaluation:
    """``ev`` of the points at ``rows`` spread over m rows, NaN elsewhere."""

    def spread(a: NDArray[np.float64] | None) -> NDArray[np.float64] | None:
        if a is None:
            return None
        out = np.full((m, *a.shape[1:]), np.nan)
        out[rows] = a
        return out

    return PointEvaluation(
        spread(ev.log_likelihood),
        spread(ev.responses),
        ev.failed_runs,
        spread(ev.log_base),
        part_runs=ev.part_runs,
        model_runs=ev.model_runs,
        failed_by=ev.failed_by,
    )


def initial_state(
    prior: JointPrior,
    samples: NDArray[np.float64],
    evaluations: Sequence[PointEvaluation],
    seed: int,
    settings: TMCMCSettings,
    tuning: tuple[float, float] | None = None,
    source: NDArray[np.int64] | None = None,
) -> StageState:
    """Stage-0 state from the samples and their evaluations (in order, concatenated).

    ``samples`` are prior draws, or, for a posterior update, the population of the earlier
    posterior prior x b evaluated by a likelihood giving log b (then ``log_prior`` = log prior +
    log b, exponent 0 targets prior x b and the evidence accumulated is Z(new | old)).
    ``tuning`` (beta, acceptance rate): the proposal scale and last acceptance rate adapted on
    the population's own target (an update: the earlier study's final stage), so stage 1 starts
    with them instead of ``beta0`` and ``initial_steps``; the kernel of a stage is still fixed
    before the stage runs, so every stage keeps its target exactly. ``source`` (n,): the
    :func:`first_occurrences` of the samples when repeated points were evaluated once
    (``copies`` in :func:`evaluate_points`); their rows take their first occurrence's values.
    """
    ll = np.concatenate([e.log_likelihood for e in evaluations])
    n = samples.shape[0]
    if ll.shape[0] != n:
        raise ValueError(f"{ll.shape[0]} evaluations for {n} samples")
    pick = _check_source(source, n)
    ran = [e for e in evaluations if e.runs > 0]
    responses = _stacked(evaluations, ran, "responses")
    base = _stacked(evaluations, ran, "log_base")
    if base is None and any(e.log_base is not None for e in ran):
        raise ValueError("some stage-0 evaluations give log b and some do not")
    log_prior = np.asarray(prior.log_pdf(samples), dtype=float)
    if base is not None:
        log_prior = log_prior + base[pick]
    ll = ll[pick]
    responses = None if responses is None else responses[pick]
    return StageState(
        stage=0,
        exponent=0.0,
        samples=np.asarray(samples, dtype=float),
        log_likelihood=ll,
        log_prior=log_prior,
        responses=responses,
        beta=_start_beta(tuning, settings),
        acceptance_rate=math.nan if tuning is None else float(tuning[1]),
        log_evidence=0.0,
        log_evidence_var=0.0,
        log_evidence_var_stagewise=0.0,
        model_runs=int(sum(e.runs for e in evaluations)),
        failed_runs=int(sum(e.failed_runs for e in evaluations)),
        failed_by=sum((e.failed_by for e in evaluations), Failures()),
        proposals=0,
        accepted=0,
        out_of_support=0,
        n_chains=0,
        n_steps=0,
        ess=float(n),
        eve=pick.astype(np.int64),  # a repeated point is one draw
        stall_count=0,
        seed=int(seed),
        part_runs=int(sum(e.part_runs for e in evaluations)),
    )


def _check_source(source: NDArray[np.int64] | None, n: int) -> NDArray[np.int64]:
    """Row indices that fill stage 0 (identity without ``source``); a source must be a row
    evaluated itself, at or before the row it fills."""
    if source is None:
        return np.arange(n)
    pick = np.asarray(source, dtype=np.int64)
    rows = np.arange(n)
    if pick.shape != (n,) or np.any(pick > rows) or np.any(pick < 0) or np.any(pick[pick] != pick):
        raise ValueError("'source' must map each of the samples to its first occurrence")
    return pick


def _stacked(
    evaluations: Sequence[PointEvaluation], ran: Sequence[PointEvaluation], name: str
) -> NDArray[np.float64] | None:
    """Field ``name`` of the evaluations concatenated (None unless every evaluation that ran
    gives it); an evaluation of copies only gives NaN rows of the same width."""
    arrays = [getattr(e, name) for e in ran]
    if not arrays or any(a is None for a in arrays):
        return None
    width = arrays[0].shape[1:]
    return np.concatenate(
        [
            getattr(e, name) if e.runs > 0 else np.full((e.log_likelihood.shape[0], *width), np.nan)
            for e in evaluations
        ],
        axis=0,
    )


def _start_beta(tuning: tuple[float, float] | None, settings: TMCMCSettings) -> float:
    if tuning is None or not math.isfinite(tuning[0]):
        return float(settings.beta0)
    return float(min(max(tuning[0], settings.beta_min), settings.beta_max))
