"""The coordinates TMCMC's random walk moves in (``TMCMCSettings.proposal_scale``).

``"linear"``: x' = x + L z in the parameters themselves (Ching & Chen 2007). ``"log"``: for
every parameter whose prior support is strictly positive (lower bound > 0) the walk moves
log x, x' = x exp((L z)_j), and the other columns stay linear. SCM's positive parameters trade
off multiplicatively (Bekker: p = (k_c / b + k_phi) z^n, so log k_phi and n are linearly
related at a given sinkage; Janosi-Hanamoto: the shear curve depends on j / J, so J scales with
the shear displacement), so their posteriors are curved ridges in x and nearly straight ones in
log x, where one Gaussian covariance (beta^2 Cov_w of the population, in walk coordinates)
fits them.

The walk stays exact: the proposal density in x is q(x' | x) = N(u' ; u, S) / prod_j x'_j over
the log columns (u = walk coordinates), so the Metropolis-Hastings ratio gains
log q(x | x') - log q(x' | x) = sum_j (log x'_j - log x_j) (:func:`log_proposal_ratio`).
Every function works row by row (results independent of the number of rows: batch-invariant).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from scm_core.inference import portable
from scm_core.inference.priors import JointPrior

__all__ = [
    "PROPOSAL_SCALES",
    "from_walk",
    "log_columns",
    "log_proposal_ratio",
    "rows_times",
    "to_walk",
]

#: accepted values of ``TMCMCSettings.proposal_scale``
PROPOSAL_SCALES = ("linear", "log")


def log_columns(prior: JointPrior, proposal_scale: str) -> NDArray[np.bool_]:
    """(d,) mask of the columns the walk moves in log coordinates."""
    if proposal_scale not in PROPOSAL_SCALES:
        raise ValueError(
            f"'proposal_scale' must be one of {PROPOSAL_SCALES}, got {proposal_scale!r}"
        )
    lower = prior.bounds[:, 0]
    return (lower > 0.0) if proposal_scale == "log" else np.zeros(lower.shape[0], dtype=bool)


def to_walk(X: NDArray[np.float64], logs: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Walk coordinates of points X (m, d): log of the ``logs`` columns."""
    U = np.array(X, dtype=float, copy=True)
    if logs.any():
        U[:, logs] = portable.log(U[:, logs])
    return U


def from_walk(U: NDArray[np.float64], logs: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Points from walk coordinates U (m, d) (inverse of :func:`to_walk`)."""
    X = np.array(U, dtype=float, copy=True)
    if logs.any():
        X[:, logs] = portable.exp(X[:, logs])
    return X


def walk_bounds(bounds: NDArray[np.float64], logs: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The prior box (d, 2) in walk coordinates."""
    return np.ascontiguousarray(to_walk(np.asarray(bounds, dtype=float).T, logs).T)


def log_proposal_ratio(
    U_new: NDArray[np.float64], U_old: NDArray[np.float64], logs: NDArray[np.bool_]
) -> NDArray[np.float64]:
    """log q(x | x') - log q(x' | x) (m,) of walk steps U_old -> U_new: the sum over the log
    columns of u'_j - u_j (0 for a linear walk), accumulated column by column."""
    out = np.zeros(U_new.shape[0])
    for j in np.flatnonzero(logs):
        out = out + (U_new[:, j] - U_old[:, j])
    return out


def rows_times(M: NDArray[np.float64], Z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows of Z @ M.T (m, M.shape[0]) by explicit column accumulation: each row's result is
    independent of the other rows (a matrix product's rounding is not)."""
    out = np.zeros((Z.shape[0], M.shape[0]))
    for j in range(Z.shape[1]):
        out = out + Z[:, j : j + 1] * M[:, j]
    return out
