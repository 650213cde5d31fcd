"""Likelihoods eq. (6) and eq. (12)-(15) against literal evaluations with scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from scm_core.inference import (
    LIKELIHOODS,
    log_likelihood_gaussian,
    log_likelihood_normalized,
    standardized_residuals,
)

X_EXP = np.array([25.0, 8.0, 0.02])  # F [N], T [N m], z [m]


def _literal_xi(x_exp, x_num, sigma):
    """eq. (14)-(15) as written: U = Phi((x_exp - x_num) / sigma) by integration, xi = Phi^-1(U)."""
    u = stats.norm.cdf(x_exp, loc=x_num, scale=sigma)
    return stats.norm.ppf(u)


def test_normalized_equals_literal_formula_where_finite() -> None:
    xi_grid = np.linspace(-40.0, 40.0, 1601)
    sigma = np.array([2.0, 0.5, 0.001])
    x_num = X_EXP - xi_grid[:, None] * sigma  # residual of xi sigma per response
    lit_xi = _literal_xi(X_EXP, x_num, sigma)
    xi = standardized_residuals(X_EXP, x_num, sigma)
    finite = np.isfinite(lit_xi)
    # the literal form is finite for xi in ~[-37.5, 8.3] only (Phi underflows / rounds to 1)
    assert 900 < finite[:, 0].sum() < 1601
    # Conditioning of Phi^-1(Phi(xi)): a rounding error dU of U moves xi by dU / pdf(xi). For
    # xi < 0, Phi is computed to a few ulp relative (dU ~ 8 eps U); for xi > 0, U = 1 - tiny is
    # stored with an absolute error of ~ulp(1) (dU ~ 8 eps). Plus 1e-12 relative for Phi^-1.
    eps = np.finfo(float).eps
    with np.errstate(all="ignore"):
        d_u = 8 * eps * np.where(xi < 0, stats.norm.cdf(xi), 1.0)
        tol = 1e-12 * (1 + np.abs(xi)) + d_u / stats.norm.pdf(xi)
    assert np.all(np.abs(lit_xi - xi)[finite] <= tol[finite])
    assert tol[finite & (xi < 0)].max() < 1e-10  # i.e. a tight check on the negative side
    lit_logp = np.where(finite, -0.5 * lit_xi**2 - 0.5 * math.log(2 * math.pi), 0.0).sum(axis=1)
    rows = finite.all(axis=1)
    logp = log_likelihood_normalized(X_EXP, x_num, sigma)
    assert logp.shape == (xi_grid.size,)
    with np.errstate(all="ignore"):
        scale = (np.abs(xi) * tol + tol**2).sum(axis=1)
    assert np.all(np.abs(lit_logp - logp)[rows] <= 1e-9 + scale[rows])


def test_normalized_is_finite_in_the_tails() -> None:
    sigma = np.array([1.0, 0.2, 0.001])
    for k in (-50.0, 50.0):
        x_num = X_EXP + k * sigma
        lit = _literal_xi(X_EXP, x_num, sigma)
        assert not np.all(np.isfinite(lit))  # the literal form breaks down here
        val = log_likelihood_normalized(X_EXP, x_num, sigma)
        assert isinstance(val, float)
        assert val == pytest.approx(3 * (-0.5 * 50**2 - 0.5 * math.log(2 * math.pi)), rel=1e-12)


def test_gaussian_matches_scipy_logpdf() -> None:
    rng = np.random.default_rng(0)
    x_num = X_EXP + rng.normal(size=(200, 3)) * [3.0, 1.0, 0.005]
    sigma = rng.uniform(0.001, 2.0, size=(200, 3))
    ref = stats.norm.logpdf(X_EXP, loc=x_num, scale=sigma).sum(axis=1)
    assert np.allclose(log_likelihood_gaussian(X_EXP, x_num, sigma), ref, rtol=1e-13, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-1e6, 1e6),
    st.floats(-1e6, 1e6),
    st.floats(1e-6, 1e6),
)
def test_gaussian_and_normalized_differ_by_log_sigma(x_exp, x_num, sigma) -> None:
    g = log_likelihood_gaussian([x_exp], [x_num], [sigma])
    n = log_likelihood_normalized([x_exp], [x_num], [sigma])
    assert g == pytest.approx(n - math.log(sigma), rel=1e-12, abs=1e-9)
    assert g == pytest.approx(stats.norm.logpdf(x_exp, x_num, sigma), rel=1e-12, abs=1e-9)


@pytest.mark.parametrize("name", ["normalized", "gaussian"])
def test_invalid_inputs_give_minus_inf(name: str) -> None:
    f = LIKELIHOODS[name]
    x_num = np.array([[25.0, 8.0, 0.02]] * 5)
    sigma = np.array([[1.0, 1.0, 0.001]] * 5)
    x_num[1, 0] = np.nan
    x_num[2, 2] = np.inf
    sigma[3, 1] = 0.0
    sigma[4, 0] = -1.0
    out = f(X_EXP, x_num, sigma)
    assert np.isfinite(out[0])
    assert np.all(out[1:] == -np.inf)


def test_sigma_identification_differs() -> None:
    """eq. (13) increases monotonically with sigma; eq. (6) peaks at sigma = |residual|."""
    resid = 0.7
    sigmas = np.linspace(0.05, 10.0, 400)
    n = log_likelihood_normalized([resid], np.zeros((400, 1)), sigmas[:, None])
    g = log_likelihood_gaussian([resid], np.zeros((400, 1)), sigmas[:, None])
    assert np.all(np.diff(n) > 0)
    assert sigmas[np.argmax(g)] == pytest.approx(resid, abs=sigmas[1] - sigmas[0])
