"""Calling a study's batch likelihood inside TMCMC: its output normalised (failed runs counted,
the base density of an update separated) and the tempered target (see
:mod:`scm_core.inference.tmcmc.stage` for the conventions)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.inference.tmcmc.types import LogLikelihoodBatch

__all__ = ["BatchOutput", "batch_output", "call_batch", "clean_log_likelihood", "tempered"]


def tempered(
    log_prior: NDArray[np.float64], log_likelihood: NDArray[np.float64], exponent: float
) -> NDArray[np.float64]:
    """log prior + exponent * log L, with 0 * (-inf) taken as 0."""
    if exponent == 0.0:
        return np.asarray(log_prior, dtype=float).copy()
    return log_prior + exponent * log_likelihood


def clean_log_likelihood(values: ArrayLike, m: int) -> tuple[NDArray[np.float64], int]:
    """Map NaN and +inf to -inf; return (log L (m,), number of non-finite values)."""
    ll = np.asarray(values, dtype=float).reshape(-1)
    if ll.shape[0] != m:
        raise ValueError(f"log_likelihood_batch returned {ll.shape[0]} values for {m} points")
    bad = ~np.isfinite(ll)
    return np.where(bad, -np.inf, ll), int(np.count_nonzero(bad))


#: (log L (m,), responses (m, k) or None, failed runs, log b (m,) or None, why each failed
#: (m,) str or None)
BatchOutput = tuple[
    NDArray[np.float64],
    NDArray[np.float64] | None,
    int,
    NDArray[np.float64] | None,
    NDArray[np.str_] | None,
]


def call_batch(log_likelihood_batch: LogLikelihoodBatch, X: NDArray[np.float64]) -> BatchOutput:
    """(log L, responses or None, failed runs, log b or None, failure reasons or None) at the
    points X (m, d); a point whose log b is not finite counts as failed and gets
    log L = log b = -inf."""
    return batch_output(log_likelihood_batch(X), X)


def batch_output(out: Any, X: NDArray[np.float64]) -> BatchOutput:
    """:func:`call_batch` from the likelihood's output ``out`` at X (see
    :data:`~scm_core.inference.tmcmc.types.LogLikelihoodBatch` for its forms). A failure
    reason is kept only where the run failed."""
    m = X.shape[0]
    base = failure = None
    if isinstance(out, tuple):
        ll_raw, resp_raw, *rest = out
        resp = np.asarray(resp_raw, dtype=float).reshape(m, -1)
        if rest and rest[0] is not None:
            base = np.asarray(rest[0], dtype=float).reshape(-1)
            if base.shape[0] != m:
                raise ValueError(f"log_likelihood_batch returned {base.shape[0]} log b for {m}")
        if len(rest) > 1 and rest[1] is not None:
            failure = np.asarray(rest[1], dtype=str).reshape(-1)
            if failure.shape[0] != m:
                raise ValueError(
                    f"log_likelihood_batch returned {failure.shape[0]} failure reasons for {m}"
                )
    else:
        ll_raw, resp = out, None
    if base is not None:
        bad_base = ~np.isfinite(base)
        ll_raw = np.where(bad_base, np.nan, np.asarray(ll_raw, dtype=float).reshape(-1))
        base = np.where(bad_base, -np.inf, base)
    ll, n_failed = clean_log_likelihood(ll_raw, m)
    if failure is not None:
        failure = np.where(np.isfinite(ll), "", failure)
    return ll, resp, n_failed, base, failure
