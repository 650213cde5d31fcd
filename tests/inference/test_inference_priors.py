"""Priors: densities against scipy, sampling, validation, serialisation, Table 2 presets."""

from __future__ import annotations

import json
import math
import pickle

import numpy as np
import pytest
from scipy import stats

from scm_core.inference import (
    TABLE2_NOMINAL,
    JointPrior,
    LogNormal,
    LogUniform,
    TruncatedNormal,
    Uniform,
    distribution_from_dict,
    table2_prior,
)


class _TruncatedLogNormal:
    """Reference: scipy's lognorm (shape log factor, scale median) renormalised on [lo, hi]."""

    def __init__(self, median: float, factor: float, lo: float, hi: float) -> None:
        self.base = stats.lognorm(math.log(factor), scale=median)
        self.lo, self.hi = lo, hi
        self.mass = self.base.cdf(hi) - self.base.cdf(lo)

    def logpdf(self, x):
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lo) & (x <= self.hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(inside, self.base.logpdf(x) - math.log(self.mass), -np.inf)

    def cdf(self, x):
        x = np.clip(np.asarray(x, dtype=float), self.lo, self.hi)
        return (self.base.cdf(x) - self.base.cdf(self.lo)) / self.mass


DISTS = [
    (Uniform(-2.0, 3.0), stats.uniform(-2.0, 5.0)),
    (TruncatedNormal(1.1, 0.2, 0.8, 2.0), stats.truncnorm(-1.5, 4.5, loc=1.1, scale=0.2)),
    (TruncatedNormal(30.0, 5.7, 11.5, 37.3), stats.truncnorm(-18.5 / 5.7, 7.3 / 5.7, 30, 5.7)),
    (LogUniform(1e3, 1e9), stats.loguniform(1e3, 1e9)),
    # a plate-test modulus known to a factor of two, truncated on both sides
    (LogNormal(8e6, 2.0, 1e6, 1e8), _TruncatedLogNormal(8e6, 2.0, 1e6, 1e8)),
    (LogNormal(0.02, 3.0, 0.0005, 0.05), _TruncatedLogNormal(0.02, 3.0, 0.0005, 0.05)),
]


@pytest.mark.parametrize(("dist", "ref"), DISTS)
def test_logpdf_matches_scipy(dist, ref) -> None:
    lo, hi = dist.lower, dist.upper
    x = np.concatenate([np.linspace(lo, hi, 501), [lo - 1e-9 * (hi - lo), hi * 1.5 + 1, np.nan]])
    got, want = dist.logpdf(x), ref.logpdf(x)
    inside = (x >= lo) & (x <= hi)
    assert np.all(got[~inside] == -np.inf)
    assert np.all(np.isfinite(got[inside]))  # closed support, bounds included
    # scipy's own support test can drop a bound by rounding (a = (lower - mean) / sd): compare
    # where scipy is finite
    ok = inside & np.isfinite(want)
    assert ok.sum() >= 499
    assert np.allclose(got[ok], want[ok], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("dist", "ref"), DISTS)
def test_sampling_matches_distribution(dist, ref) -> None:
    x = dist.sample(np.random.default_rng(0), 20000)
    assert x.shape == (20000,)
    assert x.min() >= dist.lower and x.max() <= dist.upper
    # Kolmogorov-Smirnov at n = 20000: p < 1e-3 would flag a wrong sampler
    assert stats.kstest(x, ref.cdf).pvalue > 1e-3
    again = dist.sample(np.random.default_rng(0), 20000)
    assert np.array_equal(x, again)


@pytest.mark.parametrize(("dist", "_"), DISTS)
def test_dict_roundtrip(dist, _) -> None:
    d = json.loads(json.dumps(dist.to_dict()))
    assert distribution_from_dict(d) == dist
    assert type(dist).from_dict(d) == dist
    assert pickle.loads(pickle.dumps(dist)) == dist


@pytest.mark.parametrize(
    ("factory", "field"),
    [
        (lambda: Uniform(1.0, 1.0), "upper"),
        (lambda: Uniform(math.nan, 1.0), "lower"),
        (lambda: Uniform(0.0, math.inf), "upper"),
        (lambda: TruncatedNormal(0.0, 0.0, -1.0, 1.0), "sd"),
        (lambda: TruncatedNormal(0.0, -1.0, -1.0, 1.0), "sd"),
        (lambda: TruncatedNormal(math.inf, 1.0, -1.0, 1.0), "mean"),
        (lambda: TruncatedNormal(0.0, 1.0, 2.0, 1.0), "upper"),
        (lambda: LogUniform(0.0, 1.0), "lower"),
        (lambda: LogUniform(-1.0, 1.0), "lower"),
        (lambda: LogUniform(2.0, 1.0), "upper"),
        (lambda: LogNormal(0.0, 2.0, 1.0, 2.0), "median"),
        (lambda: LogNormal(1.0, 1.0, 1.0, 2.0), "factor"),
        (lambda: LogNormal(1.0, math.nan, 1.0, 2.0), "factor"),
        (lambda: LogNormal(1.0, 2.0, 0.0, 2.0), "lower"),
        (lambda: LogNormal(1.0, 2.0, 3.0, 2.0), "upper"),
    ],
)
def test_validation_names_the_field(factory, field: str) -> None:
    with pytest.raises(ValueError, match=f"'{field}'"):
        factory()


def test_from_dict_rejects_unknown_kind() -> None:
    with pytest.raises(ValueError, match="'dist'"):
        distribution_from_dict({"dist": "cauchy", "lower": 0, "upper": 1})


def test_joint_prior_shapes_and_values() -> None:
    prior = JointPrior(
        {"a": Uniform(0.0, 2.0), "b": TruncatedNormal(0.0, 1.0, -1.0, 1.0), "c": LogUniform(1, 10)},
        units={"a": "m"},
    )
    assert prior.names == ("a", "b", "c") and prior.dim == 3
    assert np.array_equal(prior.bounds, [[0, 2], [-1, 1], [1, 10]])
    X = prior.sample(np.random.default_rng(1), 50)
    assert X.shape == (50, 3)
    assert prior.in_support(X).all()
    lp = prior.log_pdf(X)
    manual = sum(d.logpdf(X[:, j]) for j, d in enumerate(prior.dists.values()))
    assert lp.shape == (50,) and np.allclose(lp, manual, rtol=1e-14)
    assert prior.log_pdf(X[0]) == pytest.approx(lp[0], rel=1e-14)
    assert isinstance(prior.in_support(X[0]), bool)
    bad = X[:3].copy()
    bad[0, 0] = 2.5
    bad[1, 2] = np.nan
    assert list(prior.in_support(bad)) == [False, False, True]
    assert np.isneginf(prior.log_pdf(bad)[:2]).all()
    with pytest.raises(ValueError, match="shape"):
        prior.log_pdf(np.zeros((4, 2)))
    # from the unit cube
    assert np.allclose(prior.ppf(np.full(3, 0.5)), [1.0, 0.0, math.sqrt(10)])


def test_joint_prior_roundtrip_and_validation() -> None:
    prior = table2_prior("1")
    d = json.loads(json.dumps(prior.to_dict()))
    back = JointPrior.from_dict(d)
    assert back == prior and back.names == prior.names and back.units == prior.units
    with pytest.raises(ValueError, match="'units'"):
        JointPrior({"a": Uniform(0, 1)}, units={"b": "m"})
    with pytest.raises(ValueError, match="duplicate 'name'"):
        JointPrior.from_dict({"parameters": [d["parameters"][0], d["parameters"][0]]})


def test_table2_presets() -> None:
    p1, p2 = table2_prior("1"), table2_prior("2")
    assert p1.names == ("k_c", "k_phi", "n", "phi", "J", "sigma_F", "sigma_T", "sigma_z")
    assert p2.names == ("k_c", "k_phi", "n", "phi", "R", "sigma_F", "sigma_T", "sigma_z")
    assert table2_prior("2b") == p2
    assert p1.dists["k_c"] == Uniform(-1e9, 1e9)
    assert p1.dists["k_phi"] == Uniform(1.0, 1e10)
    assert p1.dists["n"] == TruncatedNormal(1.1, 0.2, 0.8, 2.0)
    assert p1.dists["phi"] == TruncatedNormal(30.0, 5.7, 11.5, 37.3)
    assert p1.dists["J"] == Uniform(0.001, 0.1)
    assert p2.dists["R"] == Uniform(0.125, 0.155)
    assert p1.dists["sigma_F"] == Uniform(0.0, 5.0)
    assert p1.dists["sigma_T"] == Uniform(0.0, 10.0)
    assert p1.dists["sigma_z"] == Uniform(0.0, 0.005)
    assert p1.units["phi"] == "deg"
    assert TABLE2_NOMINAL == {"J": 0.001, "R": 0.125}
    with pytest.raises(ValueError, match="'case'"):
        table2_prior("3")
    X = p1.sample(np.random.default_rng(0), 100)
    assert np.isfinite(p1.log_pdf(X)).all()


def test_log_normal_quantiles_are_the_factor() -> None:
    """Untruncated in effect (bounds 10 sd away): the median and one geometric sd either side."""
    dist = LogNormal(8e6, 2.0, 8e6 / 2.0**10, 8e6 * 2.0**10)
    q = dist.ppf(stats.norm.cdf([-1.0, 0.0, 1.0]))
    assert np.allclose(q, [4e6, 8e6, 16e6], rtol=1e-9)
    # the density integrates to one over its support (log-spaced trapezoid)
    x = np.geomspace(dist.lower, dist.upper, 200001)
    assert np.trapezoid(np.exp(dist.logpdf(x)), x) == pytest.approx(1.0, abs=1e-6)
