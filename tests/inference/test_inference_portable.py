"""The CPU-independent numerics (scm_core.inference.portable, issue 71) against numpy's and
scipy's own: the same values to the last few bits (they differ from numpy only in rounding,
which is what varies across CPUs), and the edge cases numpy defines."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import logsumexp as scipy_logsumexp

from scm_core.inference import portable

RNG = np.random.default_rng(3)


def test_elementwise_functions_are_numpys_to_two_ulps() -> None:
    """Both are within an ulp of the exact value (the C library's and numpy's AVX-512
    versions), so they differ by at most two: 4.5e-16 relative."""
    x = RNG.normal(size=10_001) * 20
    assert np.allclose(portable.exp(x / 4), np.exp(x / 4), rtol=4.5e-16, atol=0)
    a = np.abs(x) + 1e-3
    assert np.allclose(portable.log(a), np.log(a), rtol=4.5e-16, atol=1e-300)
    assert np.allclose(portable.log1p(a), np.log1p(a), rtol=4.5e-16, atol=0)
    assert portable.exp(x[:70].reshape(7, 10)).shape == (7, 10)
    with np.errstate(divide="ignore", invalid="ignore"):
        for f, g, edge in ((portable.log, np.log, [0.0, -1.0, np.inf]),
                           (portable.log1p, np.log1p, [-1.0, -2.0, np.inf])):  # fmt: skip
            assert np.array_equal(f(np.array(edge)), g(np.array(edge)), equal_nan=True)
    assert portable.exp(np.array([-np.inf, np.inf, 800.0]))[0] == 0.0


@pytest.mark.parametrize(
    "a", [RNG.normal(size=500) * 50, np.array([-np.inf, 1.0, 2.0]), np.array([3.0])]
)
def test_logsumexp_is_scipys(a) -> None:
    assert portable.logsumexp(a) == pytest.approx(scipy_logsumexp(a), rel=1e-14, abs=1e-14)


def test_logsumexp_of_nothing_is_minus_infinity() -> None:
    assert portable.logsumexp(np.array([-np.inf, -np.inf])) == -np.inf
    assert portable.logsumexp(np.array([])) == -np.inf


def test_weighted_moments_and_factors_are_numpys() -> None:
    X = RNG.normal(size=(400, 6)) @ RNG.normal(size=(6, 6))
    w = RNG.random(400)
    w /= w.sum()
    mean = w @ X
    cov = ((X - mean) * w[:, None]).T @ (X - mean)
    assert np.allclose(portable.weighted_mean(X, w), mean, rtol=1e-13, atol=1e-14)
    C = portable.weighted_covariance(X, w)
    assert np.array_equal(C, C.T) and np.allclose(C, cov, rtol=1e-12, atol=1e-14)
    L = portable.cholesky(C)
    assert np.allclose(L, np.linalg.cholesky(C), rtol=1e-12, atol=1e-13)
    assert np.allclose(portable.lower_inverse(L) @ L, np.eye(6), atol=1e-12)
    with pytest.raises(np.linalg.LinAlgError):
        portable.cholesky(-np.eye(3))


def test_systems_are_solved_as_lapack_solves_them_and_a_singular_one_is_nan() -> None:
    A = RNG.normal(size=(50, 12, 12)) + 4 * np.eye(12)
    B = RNG.normal(size=(50, 12, 3))
    A[7] = 0.0  # singular
    got = portable.solve_systems(A, B)
    ok = np.arange(50) != 7
    assert np.allclose(got[ok], np.linalg.solve(A[ok], B[ok]), rtol=1e-10, atol=1e-12)
    assert np.isnan(got[7]).all()
    # a system that needs row exchanges (zero leading pivot)
    P = np.array([[[0.0, 1.0], [1.0, 0.0]]])
    assert np.array_equal(portable.solve_systems(P, np.array([[[2.0], [3.0]]])), [[[3.0], [2.0]]])
