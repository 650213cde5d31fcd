"""Population jumps (scm_core.inference.population_jump) against scipy's multivariate t."""

from __future__ import annotations

import numpy as np
from scipy import stats

from scm_core.inference.population_jump import JUMP_DOF, jump_log_density, jump_proposal

MEAN = np.array([1.0, -2.0, 0.5])
COV = np.array([[2.0, 0.6, -0.3], [0.6, 1.0, 0.2], [-0.3, 0.2, 0.5]])


def test_log_density_is_scipys_multivariate_t_up_to_its_constant() -> None:
    chol = np.linalg.cholesky(COV)
    U = np.random.default_rng(0).normal(size=(50, 3)) * 3.0
    ours = jump_log_density(U, MEAN, np.linalg.inv(chol))
    exact = stats.multivariate_t(loc=MEAN, shape=COV, df=JUMP_DOF).logpdf(U)
    np.testing.assert_allclose(ours - exact, (ours - exact)[0], atol=1e-10)


def test_draws_follow_the_t() -> None:
    """(u - m)^T S^-1 (u - m) / d of a t_nu draw is F(d, nu) distributed; 20,000 draws: the
    KS statistic's 1 % critical value is 1.63 / sqrt(20000) = 0.012."""
    rng = np.random.default_rng(1)
    n, d = 20_000, 3
    chol = np.linalg.cholesky(COV)
    U = jump_proposal(MEAN, chol, rng.standard_normal((n, d)), rng.chisquare(JUMP_DOF, n))
    dev = U - MEAN
    q = np.einsum("ij,jk,ik->i", dev, np.linalg.inv(COV), dev) / d
    assert stats.kstest(q, stats.f(d, JUMP_DOF).cdf).statistic < 0.012


def test_rows_do_not_depend_on_the_batch() -> None:
    rng = np.random.default_rng(2)
    chol = np.linalg.cholesky(COV)
    Z, chi2 = rng.standard_normal((7, 3)), rng.chisquare(JUMP_DOF, 7)
    whole = jump_proposal(MEAN, chol, Z, chi2)
    inv = np.linalg.inv(chol)
    dens = jump_log_density(whole, MEAN, inv)
    for i in range(7):
        np.testing.assert_array_equal(
            jump_proposal(MEAN, chol, Z[i : i + 1], chi2[i : i + 1]), whole[i : i + 1]
        )
        np.testing.assert_array_equal(
            jump_log_density(whole[i : i + 1], MEAN, inv), dens[i : i + 1]
        )
