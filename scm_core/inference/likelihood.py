"""Log-likelihoods of steady SWT responses (paper section 2 eq. (6) and section 4.3 eq. (12)-(15)).

Both functions take experimental means ``x_exp`` (k,), simulated means ``x_num`` (..., k) and
prediction-error standard deviations ``sigma`` (..., k) in the responses' own units (F in N, T in
N m, z in m), broadcast them, and sum over the last (response) axis. Rows with a non-finite
``x_num`` or a ``sigma`` that is not finite and > 0 get -inf; nothing is raised.

The two forms differ in how they identify sigma:

* eq. (6), ``gaussian``: prod_i N(x_exp,i; x_num,i, sigma_i^2) carries the 1/sigma_i factor, so a
  sigma far larger than the residual is penalised and sigma is identified (its posterior
  concentrates around the size of the residuals).
* eq. (13)-(15), ``normalized``: each factor is the standard-normal density of
  xi_i = Phi^-1(U_i) = (x_exp,i - x_num,i) / sigma_i, without the 1/sigma_i factor. It grows
  monotonically as sigma_i grows (xi_i -> 0), so sigma_i is not identified: its posterior piles up
  against the upper bound of its prior, and the data are effectively weighted by that bound.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.inference import portable

__all__ = [
    "LIKELIHOODS",
    "LOG_SQRT_2PI",
    "log_likelihood_gaussian",
    "log_likelihood_normalized",
    "log_likelihood_trials",
    "standardized_residuals",
]

LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def standardized_residuals(
    x_exp: ArrayLike, x_num: ArrayLike, sigma: ArrayLike
) -> NDArray[np.float64]:
    """xi = (x_exp - x_num) / sigma, eq. (14)-(15).

    U_i of eq. (15) is Phi((x_exp - x_num) / sigma), so Phi^-1(U_i) is this ratio exactly; it is
    computed directly because Phi then Phi^-1 loses all precision (and overflows) in the tails.
    Entries with invalid sigma (<= 0 or non-finite) or non-finite x_num are NaN.
    """
    x_exp, x_num, sigma = np.broadcast_arrays(
        np.asarray(x_exp, dtype=float), np.asarray(x_num, dtype=float), np.asarray(sigma, float)
    )
    valid = np.isfinite(x_num) & np.isfinite(sigma) & (sigma > 0) & np.isfinite(x_exp)
    with np.errstate(all="ignore"):
        xi = (x_exp - x_num) / sigma
    return np.where(valid, xi, np.nan)


def _sum_responses(terms: NDArray[np.float64]) -> NDArray[np.float64] | float:
    """Sum over the last axis in response order; NaN terms make the row -inf."""
    if terms.ndim == 0:
        terms = terms.reshape(1)
    total = np.zeros(terms.shape[:-1])
    for i in range(terms.shape[-1]):
        total = total + terms[..., i]
    total = np.where(np.isnan(total), -np.inf, total)
    return float(total) if total.ndim == 0 else total


def log_likelihood_normalized(
    x_exp: ArrayLike, x_num: ArrayLike, sigma: ArrayLike
) -> NDArray[np.float64] | float:
    """Paper's normalised log-likelihood, eq. (12)-(15): sum_i [-xi_i^2 / 2 - log sqrt(2 pi)].

    ``xi_i = (x_exp,i - x_num,i) / sigma_i`` (see :func:`standardized_residuals`). There is no
    1/sigma_i factor (eq. (13)), so the value increases monotonically with sigma_i and the
    posterior of sigma_i piles against its prior's upper bound; use :func:`log_likelihood_gaussian`
    to identify sigma. Finite for any finite residual (e.g. 50 sigma gives -1250.92).
    Returns a float for 1-D inputs, else an array over the leading axes; -inf for invalid rows.
    """
    xi = standardized_residuals(x_exp, x_num, sigma)
    return _sum_responses(-0.5 * xi * xi - LOG_SQRT_2PI)


def log_likelihood_gaussian(
    x_exp: ArrayLike, x_num: ArrayLike, sigma: ArrayLike
) -> NDArray[np.float64] | float:
    """Standard Gaussian log-likelihood, eq. (6): sum_i log N(x_exp,i; x_num,i, sigma_i^2).

    Equals sum_i [-xi_i^2 / 2 - log sqrt(2 pi) - log sigma_i]; the -log sigma_i term (the 1/sigma_i
    factor of eq. (6)) penalises large sigma, so sigma is identified by the data.
    Returns a float for 1-D inputs, else an array over the leading axes; -inf for invalid rows.
    """
    xi = standardized_residuals(x_exp, x_num, sigma)
    sigma_b = np.broadcast_to(np.asarray(sigma, dtype=float), xi.shape)
    log_sigma = portable.log(np.where(np.isnan(xi), 1.0, sigma_b))
    return _sum_responses(-0.5 * xi * xi - LOG_SQRT_2PI - log_sigma)


def log_likelihood_trials(
    likelihood: str,
    x_mean: ArrayLike,
    x_sd: ArrayLike,
    n_trials: int,
    x_num: ArrayLike,
    sigma: ArrayLike,
) -> NDArray[np.float64] | float:
    """Eq. (6) or (12)-(15) summed over the n repeated trials of one test condition, from their
    sufficient statistics: the trial mean ``x_mean``, the sample sd ``x_sd`` (ddof = 1, same
    units) and n.

    Every trial j is a test with the same simulated mean x_num, and
    sum_j (x_j - x_num)^2 = (n - 1) sd^2 + n (x_mean - x_num)^2, so the sum is
    n * L1(x_mean) - sum_i (n - 1) sd_i^2 / (2 sigma_i^2), L1 the one-test form. Exactly what the
    trials give uploaded as n datasets of one trial each; n = 1 is the one-test form.
    """
    func = LIKELIHOODS[likelihood]
    one = np.asarray(func(x_mean, x_num, sigma), dtype=float)
    if n_trials == 1:
        return float(one) if one.ndim == 0 else one
    sd, sig = np.broadcast_arrays(np.asarray(x_sd, dtype=float), np.asarray(sigma, dtype=float))
    with np.errstate(all="ignore"):
        scatter = ((n_trials - 1) * sd * sd / (2.0 * sig * sig)).sum(axis=-1)
    total = n_trials * one - scatter
    total = np.where(np.isnan(total), -np.inf, total)
    return float(total) if total.ndim == 0 else total


LIKELIHOODS: dict[str, Callable[[ArrayLike, ArrayLike, ArrayLike], NDArray[np.float64] | float]] = {
    "normalized": log_likelihood_normalized,
    "gaussian": log_likelihood_gaussian,
}
