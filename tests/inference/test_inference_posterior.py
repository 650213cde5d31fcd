"""Posterior summaries, credible intervals, kernel densities and pooling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from scm_core.inference import (
    JointPrior,
    Uniform,
    credible_interval,
    kde_1d,
    kde_2d,
    map_sample,
    pool_samples,
    run_tmcmc,
    summarize,
    summarize_result,
)


@pytest.fixture(scope="module")
def gaussian_samples() -> np.ndarray:
    cov = np.array([[1.0, 0.8], [0.8, 4.0]])
    return np.random.default_rng(0).multivariate_normal([1.0, -2.0], cov, size=20000)


def test_summary_statistics(gaussian_samples) -> None:
    s = summarize(gaussian_samples, names=["a", "b"])
    # n = 20000 independent draws: se(mean) = sd / 141, se(sd) = sd / 200; 4 se tolerances
    assert np.allclose(s.mean, [1.0, -2.0], atol=4 * np.array([1.0, 2.0]) / 141)
    assert np.allclose(s.sd, [1.0, 2.0], rtol=4 / 200)
    assert s.correlation[0, 1] == pytest.approx(0.4, abs=0.02)
    assert s.quantiles.shape == (5, 2)
    exact = stats.norm.ppf(s.quantile_levels)
    assert np.allclose(s.quantiles[:, 0], 1.0 + exact, atol=0.05)
    assert s.map_sample is None
    rows = s.as_rows()
    assert rows[1]["name"] == "b" and "q2.5" in rows[1] and "q97.5" in rows[1]


def test_credible_interval(gaussian_samples) -> None:
    ci = credible_interval(gaussian_samples, 0.9)
    assert ci.shape == (2, 2)
    assert np.allclose(ci[0], [1.0 - 1.645, 1.0 + 1.645], atol=0.05)
    assert credible_interval(gaussian_samples[:, 0], 0.5).shape == (2,)
    frac = np.mean((gaussian_samples[:, 1] >= ci[1, 0]) & (gaussian_samples[:, 1] <= ci[1, 1]))
    assert frac == pytest.approx(0.9, abs=1e-3)
    with pytest.raises(ValueError):
        credible_interval(gaussian_samples, 1.5)


def test_map_sample() -> None:
    X = np.arange(10.0)[:, None]
    lp = np.zeros(10)
    ll = -((X[:, 0] - 6.2) ** 2)
    ll[3] = np.nan
    best, value = map_sample(X, lp, ll)
    assert best[0] == 6.0 and value == pytest.approx(-0.04)


def test_kde_1d_integrates_to_one_and_reflects(gaussian_samples) -> None:
    g, dens = kde_1d(gaussian_samples[:, 0])
    assert np.trapezoid(dens, g) == pytest.approx(1.0, abs=1e-3)
    assert dens[np.argmax(dens)] == pytest.approx(stats.norm.pdf(0), rel=0.05)
    # samples piled against an upper bound at 1: the reflected density keeps its mass inside
    x = np.random.default_rng(1).uniform(0.0, 1.0, 5000) ** 0.3
    g, dens = kde_1d(x, bounds=(0.0, 1.0))
    assert g[0] == 0.0 and g[-1] == 1.0
    assert np.trapezoid(dens, g) == pytest.approx(1.0, abs=0.02)
    assert dens[-1] > dens[len(g) // 2]  # true pdf x^(7/3) / 0.3 rises to the bound


def test_kde_2d_grid(gaussian_samples) -> None:
    gx, gy, dens = kde_2d(gaussian_samples[:2000, 0], gaussian_samples[:2000, 1], n_grid=80)
    assert dens.shape == (80, 80)
    mass = np.trapezoid(np.trapezoid(dens, gx, axis=1), gy)
    assert mass == pytest.approx(1.0, abs=0.02)
    iy, ix = np.unravel_index(np.argmax(dens), dens.shape)
    assert gx[ix] == pytest.approx(1.0, abs=0.3) and gy[iy] == pytest.approx(-2.0, abs=0.6)


@pytest.mark.parametrize("shape", ["gaussian", "piled against a bound"])
def test_kde_2d_contours_close_inside_the_grid(gaussian_samples, shape) -> None:
    """The dashboard draws contours from 5 % of the maximum up: the density on the grid's
    edge lies below that level, so every contour closes (a TMCMC stage: 400 samples)."""
    x, y = gaussian_samples[:400, 0], gaussian_samples[:400, 1]
    if shape != "gaussian":
        x = np.random.default_rng(2).uniform(0.0, 1.0, 400) ** 0.3
    *_, dens = kde_2d(x, y, n_grid=80)
    edge = np.concatenate([dens[0], dens[-1], dens[:, 0], dens[:, -1]])
    assert edge.max() < 0.05 * dens.max() * 0.2


def test_pool_samples_equal_weight_per_run() -> None:
    a = np.zeros((100, 2))
    b = np.ones((300, 2))
    pooled = pool_samples([a, b], seed=0)
    assert pooled.shape == (200, 2)
    assert pooled[:, 0].mean() == 0.5  # equal weight per run despite unequal sizes
    assert np.array_equal(pool_samples([a, b], seed=0), pooled)
    with pytest.raises(ValueError):
        pool_samples([a, b], n_per_run=200)


def loglik_peak(X: np.ndarray) -> np.ndarray:
    return -0.5 * ((X[:, 0] - 0.3) / 0.05) ** 2


def test_summarize_result_gives_map_near_mode() -> None:
    prior = JointPrior({"k": Uniform(0.0, 1.0)})
    res = run_tmcmc(loglik_peak, prior, n_samples=500, seed=0)
    s = summarize_result(res)
    assert s.names == ("k",)
    assert s.map_sample is not None and s.map_sample[0] == pytest.approx(0.3, abs=0.01)
    assert s.mean[0] == pytest.approx(0.3, abs=0.01)
