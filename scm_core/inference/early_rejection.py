"""Early rejection across likelihood parts: an exact saving inside TMCMC's Metropolis moves.

A study's likelihood is a product over independent parts (its datasets: one simulator run
each). A Metropolis move accepts x' when log u < log pi(x') - log pi(x), with
log pi = log prior + sum_k w_k l_k (w_k = 1 for a part of the base density of an update, the
stage exponent p for a tempered part). Drawing u first (:func:`run_chains` draws every chain's
u before its steps) fixes the threshold T = log u + log pi(x) - log prior(x'); the parts are
then run one after another (cheapest first) and the proposal is rejected as soon as

    sum_{k done} w_k l_k(x') + sum_{k left} w_k max l_k(x') < T,

the maximum being the part's largest possible value at x' (a Gaussian term at zero residual:
-sum log(sqrt(2 pi) sigma)). The decision is the one the full evaluation would make, so the
chains, samples and evidences are bit-identical with and without it; only the runs differ
(Solonen et al. 2012, "Efficient MCMC for climate model parameter estimation: parallel
adaptive chains and early rejection", Bayesian Analysis 7(3)).

A likelihood opts in by implementing :class:`PartedLikelihood`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = ["PartedLikelihood", "StagedEvaluation", "evaluate_staged", "is_parted", "n_parts"]

#: relative margin of the early test: a proposal is rejected early only if its bound misses the
#: threshold by more than rounding could account for (sums taken in another order)
_REL_TOL = 1e-9


@runtime_checkable
class PartedLikelihood(Protocol):
    """A likelihood ``f(X)`` that is a sum of independent parts, evaluable one at a time.

    ``part_order``: the order to run the parts in (cheapest first); ``part_in_base``: part k
    belongs to the base density b of an update (weight 1, not tempered). ``run_part(X, k)``:
    (log term of part k (m,), its responses (m, r_k)) or (term, responses, failure (m,): why a
    run failed, in the model's words, "" where it did not); a failed run gives a non-finite
    term.
    ``part_bound(X, k)``: an upper bound (m,) of part k's log term at X (``inf`` if none).
    ``assemble(X, responses)``: from every part's responses (list over k, canonical order), the
    exact output of ``f(X)`` (bit-identical: the same arithmetic in the same order).
    """

    part_order: tuple[int, ...]
    part_in_base: tuple[bool, ...]

    def run_part(
        self, X: NDArray[np.float64], k: int
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...

    def part_bound(self, X: NDArray[np.float64], k: int) -> NDArray[np.float64]: ...

    def assemble(self, X: NDArray[np.float64], responses: Sequence[NDArray[np.float64]]): ...


def is_parted(f: object) -> bool:
    """Whether ``f`` can be evaluated part by part (and has more than one part)."""
    return isinstance(f, PartedLikelihood) and len(f.part_order) > 1


def n_parts(f: object) -> int:
    """Parts one full evaluation of ``f`` runs (a study's datasets; 1 if not parted)."""
    return len(f.part_in_base) if is_parted(f) else 1  # type: ignore[attr-defined]


@dataclass(frozen=True, eq=False)
class StagedEvaluation:
    """Result of :func:`evaluate_staged` at m proposals.

    ``complete`` (m,): proposals whose every part ran (``output`` is ``f``'s output at
    ``X[complete]``, None if none did); ``rejected`` (m,): proposals rejected before their last
    part (the full evaluation would reject them too); ``part_runs``: parts run in total;
    ``part_runs_saved``: parts not run thanks to the early test; ``failed_rejected``: rejected
    proposals one of whose parts failed (a failed run ends a proposal at once); ``failure``
    (m,): the reason of each proposal's first failed run where the parts give reasons (""
    where none failed), else None.
    """

    complete: NDArray[np.bool_]
    rejected: NDArray[np.bool_]
    output: object
    part_runs: int
    part_runs_saved: int
    failed_rejected: int
    failure: NDArray[np.str_] | None = None


def evaluate_staged(
    f: PartedLikelihood,
    X: NDArray[np.float64],
    threshold: NDArray[np.float64],
    exponent: float,
) -> StagedEvaluation:
    """Run the parts of ``f`` at proposals X (m, d) in ``f.part_order``, dropping a proposal
    once its weighted log terms so far plus the bounds of the parts left fall below
    ``threshold`` (m,) (see the module doc; weights 1 for base parts, ``exponent`` else)."""
    X = np.asarray(X, dtype=float)
    m = X.shape[0]
    n_parts = len(f.part_in_base)
    weight = np.array([1.0 if b else float(exponent) for b in f.part_in_base])
    bounds = np.empty((m, n_parts))
    for k in range(n_parts):
        with np.errstate(invalid="ignore"):
            bounds[:, k] = weight[k] * np.asarray(f.part_bound(X, k), dtype=float).reshape(-1)
    bounds = np.where(np.isnan(bounds), np.inf, bounds)
    responses: list[NDArray[np.float64] | None] = [None] * n_parts
    alive = np.ones(m, dtype=bool)
    rejected = np.zeros(m, dtype=bool)
    failed = np.zeros(m, dtype=bool)
    reasons: NDArray[np.object_] | None = None
    done_sum = np.zeros(m)
    done_abs = np.zeros(m)
    left = bounds.sum(axis=1)
    runs = 0
    for k in f.part_order:
        rows = np.flatnonzero(alive)
        left = left - bounds[:, k]
        if rows.size == 0:
            break
        term, resp, *why = f.run_part(X[rows], k)
        if why:
            if reasons is None:
                reasons = np.full(m, "", dtype=object)
            first = reasons[rows] == ""
            reasons[rows[first]] = np.asarray(why[0], dtype=object).reshape(-1)[first]
        term = np.asarray(term, dtype=float).reshape(-1)
        resp = np.asarray(resp, dtype=float).reshape(rows.size, -1)
        if responses[k] is None:
            responses[k] = np.full((m, resp.shape[1]), np.nan)
        responses[k][rows] = resp
        runs += rows.size
        with np.errstate(invalid="ignore"):
            wt = weight[k] * term if weight[k] != 0.0 else np.zeros_like(term)
        wt = np.where(np.isfinite(term), wt, -np.inf)
        failed[rows] |= ~np.isfinite(term)
        done_sum[rows] = done_sum[rows] + wt
        done_abs[rows] = done_abs[rows] + np.abs(np.where(np.isfinite(wt), wt, 0.0))
        reach = done_sum[rows] + left[rows]
        finite_left = np.where(np.isfinite(left[rows]), np.abs(left[rows]), 0.0)
        finite_t = np.where(np.isfinite(threshold[rows]), np.abs(threshold[rows]), 0.0)
        tol = _REL_TOL * (1.0 + finite_t + done_abs[rows] + finite_left)
        with np.errstate(invalid="ignore"):
            stop = reach < threshold[rows] - tol
        if k != f.part_order[-1]:
            rejected[rows[stop]] = True
            alive[rows[stop]] = False
    complete = alive
    output = None
    if complete.any():
        idx = np.flatnonzero(complete)
        output = f.assemble(X[idx], [r[idx] for r in responses])  # type: ignore[index]
    saved = m * n_parts - runs
    failure = None
    if reasons is not None:
        failure = np.where(failed, reasons, "").astype(str)
    return StagedEvaluation(
        complete, rejected, output, runs, saved, int(np.count_nonzero(rejected & failed)), failure
    )
