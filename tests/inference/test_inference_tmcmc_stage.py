"""Unit tests of the TMCMC stage functions and of failure handling."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from scm_core.inference import JointPrior, TMCMCSettings, Uniform, run_tmcmc
from scm_core.inference.tmcmc.stage import (
    adapt_beta,
    multinomial_resample,
    next_exponent,
    plausibility_weights,
    steps_for_acceptance,
    systematic_resample,
    weighted_covariance,
)
from scm_core.inference.tmcmc.weights import genealogy_log_evidence_var


def _cov(logl: np.ndarray, dp: float) -> float:
    w = np.where(np.isfinite(logl), np.exp(dp * np.where(np.isfinite(logl), logl, 0.0)), 0.0)
    return float(w.std() / w.mean())


def test_next_exponent_hits_target_cov() -> None:
    logl = np.random.default_rng(0).normal(-50.0, 10.0, size=2000)
    p = next_exponent(logl, 0.0, target_cov=1.0)
    assert 0.0 < p < 1.0
    assert _cov(logl, p) == pytest.approx(1.0, rel=1e-6)
    p2 = next_exponent(logl, p, target_cov=1.0)
    assert p2 > p
    assert _cov(logl, p2 - p) == pytest.approx(1.0, rel=1e-6)


def test_next_exponent_caps_at_one_and_handles_huge_values() -> None:
    assert next_exponent(np.full(100, -3.0), 0.2) == 1.0  # flat: CoV 0 everywhere
    logl = np.linspace(-1e12, 0.0, 1000)  # would overflow exp() without log-space weights
    p = next_exponent(logl, 0.0)
    assert 0.0 < p < 1e-9
    assert _cov(logl, p) == pytest.approx(1.0, rel=1e-5)


def test_next_exponent_with_minus_inf_likelihoods() -> None:
    logl = np.concatenate([np.full(30, -np.inf), np.random.default_rng(1).normal(0, 1, 70)])
    p = next_exponent(logl, 0.0)
    assert 0.0 < p <= 1.0
    w, _ = plausibility_weights(logl, p)
    assert np.all(w[:30] == 0.0) and w.sum() == pytest.approx(1.0)
    # -inf samples make CoV(0+) = sqrt(100/70 - 1) = 0.65 < 1, so the step is a real one
    assert p > 1e-3
    # 60 % of failures already exceed the target CoV: a tiny step that only removes them
    logl2 = np.concatenate([np.full(60, -np.inf), np.zeros(40)])
    p2 = next_exponent(logl2, 0.3)
    assert p2 == 1.0 or p2 > 0.3
    _, log_s2 = plausibility_weights(logl2, p2 - 0.3)
    assert log_s2 == pytest.approx(math.log(0.4))
    with pytest.raises(ValueError):
        next_exponent(np.full(5, -np.inf), 0.0)


def test_systematic_resampling_counts() -> None:
    w = np.array([0.5, 0.0, 0.25, 0.125, 0.125])
    idx = systematic_resample(w, 8, np.random.default_rng(0))
    counts = np.bincount(idx, minlength=5)
    assert np.array_equal(counts, [4, 0, 2, 1, 1])  # exact for weights that are multiples of 1/n
    w = np.random.default_rng(1).dirichlet(np.ones(50))
    counts = np.bincount(systematic_resample(w, 1000, np.random.default_rng(2)), minlength=50)
    assert np.all(np.abs(counts - 1000 * w) < 1.0 + 1e-9)


def test_multinomial_resampling_draws_independently_in_proportion_to_the_weights() -> None:
    w = np.array([0.5, 0.0, 0.25, 0.125, 0.125])
    idx = multinomial_resample(w, 8, np.random.default_rng(0))
    assert idx.shape == (8,) and np.all(np.diff(idx) >= 0) and not np.any(idx == 1)
    assert np.array_equal(idx, multinomial_resample(w, 8, np.random.default_rng(0)))
    # counts of 20,000 draws over 50 categories against the multinomial: chi-square test
    w = np.random.default_rng(1).dirichlet(np.ones(50))
    counts = np.bincount(multinomial_resample(w, 20_000, np.random.default_rng(2)), minlength=50)
    assert stats.chisquare(counts, 20_000 * w).pvalue > 1e-3


def test_genealogy_variance_closed_forms() -> None:
    """Lee & Whiteley's estimate in the cases it reduces to something known."""
    w = np.random.default_rng(0).random(60)
    w /= w.sum()
    # first weighting, every sample its own Eve: the unbiased form of the delta method,
    # 1 - n / (n - 1) (1 - sum w^2) = (n sum w^2 - 1) / (n - 1)
    got = genealogy_log_evidence_var(w, np.arange(60), 1, 60, 60)
    assert got == pytest.approx((60 * np.sum(w * w) - 1.0) / 59.0, rel=1e-12)
    # equal weights on n independent draws: no error
    assert genealogy_log_evidence_var(np.full(60, 1 / 60), np.arange(60), 1, 60, 60) == (
        pytest.approx(0.0, abs=1e-12)
    )
    # a population descended from one Eve: Z-hat rests on one draw, relative variance 1
    assert genealogy_log_evidence_var(w, np.zeros(60, np.int64), 5, 60, 12) == pytest.approx(1.0)
    # ten Eves of six samples after three weightings (waste-free-like: 12 draws each later)
    eve = np.repeat(np.arange(10), 6)
    w_eve = np.bincount(eve, weights=w)
    want = 1.0 - 60 / 59 * (12 / 11) ** 2 * (1.0 - np.sum(w_eve**2))
    assert genealogy_log_evidence_var(w, eve, 3, 60, 12) == pytest.approx(want, rel=1e-12)


def test_evidence_variance_is_the_genealogy_estimate_above_the_stagewise_sum() -> None:
    """Either resampling scheme reports the genealogy estimate, never below the sum of the
    per-stage terms, which is kept beside it (log_evidence_var_stagewise); a state stored
    before Eves and that sum were kept accumulates the previous variance plus the increment's.
    Eves follow the resampling: every sample descends from the Eve of its chain's start."""
    import dataclasses

    from scm_core.inference import plan_stage

    prior = JointPrior({"x": Uniform(-1.0, 1.0)})

    def f(X: np.ndarray) -> np.ndarray:
        return -0.5 * (X[:, 0] / 0.1) ** 2

    for settings in (TMCMCSettings(), TMCMCSettings(resampling="multinomial")):
        res = run_tmcmc(f, prior, n_samples=200, seed=0, settings=settings)
        assert np.array_equal(res.stages[0].eve, np.arange(200))
        assert res.stages[0].log_evidence_var_stagewise == 0.0
        for k, (prev, state) in enumerate(zip(res.stages[:-1], res.stages[1:], strict=True)):
            plan = plan_stage(prev, prior, settings)
            assert np.array_equal(np.unique(state.eve), np.unique(prev.eve[plan.parent]))
            summed = prev.log_evidence_var_stagewise + plan.log_evidence_increment_var
            assert state.log_evidence_var_stagewise == summed
            genealogy = genealogy_log_evidence_var(
                plan.weights, prev.eve, k + 1, 200, 200, settings.resampling
            )
            assert state.log_evidence_var == max(genealogy, summed)
        assert res.log_evidence_se == math.sqrt(res.final.log_evidence_var)
        stored = dataclasses.replace(res.stages[1], eve=None, log_evidence_var_stagewise=math.nan)
        plan = plan_stage(stored, prior, settings)
        assert plan.start_eve is None
        want = stored.log_evidence_var + plan.log_evidence_increment_var
        assert plan.log_evidence_var == pytest.approx(want, rel=1e-12)
        assert plan.log_evidence_var_stagewise == pytest.approx(want, rel=1e-12)
    with pytest.raises(ValueError, match="resampling"):
        TMCMCSettings(resampling="stratified")


def test_weighted_covariance_matches_numpy() -> None:
    rng = np.random.default_rng(3)
    X = rng.normal(size=(400, 3))
    w = rng.random(400)
    ref = np.cov(X, rowvar=False, aweights=w, bias=True)
    assert np.allclose(weighted_covariance(X, w / w.sum()), ref, rtol=1e-12, atol=1e-14)


def test_steps_for_acceptance_and_beta_adaptation() -> None:
    assert steps_for_acceptance(0.234, 0.99, 1, 100) == math.ceil(math.log(0.01) / math.log(0.766))
    assert steps_for_acceptance(0.0, 0.99, 5, 40) == 40
    assert steps_for_acceptance(0.9, 0.99, 5, 40) == 5
    s = TMCMCSettings()
    assert adapt_beta(0.2, 0.8, s) > 0.2 > adapt_beta(0.2, 0.05, s)
    assert adapt_beta(0.2, s.target_acceptance, s) == pytest.approx(0.2)
    assert adapt_beta(s.beta_max, 1.0, s) == s.beta_max
    assert adapt_beta(0.3, math.nan, s) == 0.3


def test_settings_validation() -> None:
    with pytest.raises(ValueError, match="moves"):
        TMCMCSettings(moves="gibbs")
    with pytest.raises(ValueError, match="n_steps"):
        TMCMCSettings(n_steps=0)
    with pytest.raises(ValueError, match="target_cov"):
        TMCMCSettings(target_cov=0.0)
    assert TMCMCSettings.from_dict(TMCMCSettings(n_steps=4).to_dict()) == TMCMCSettings(n_steps=4)


# --- failures -------------------------------------------------------------------------------

SD_F = 0.3


def loglik_with_holes(X: np.ndarray) -> np.ndarray:
    """Gaussian at the origin; NaN for x0 > 0.5, -inf for x1 < -0.5 (simulator failures)."""
    r = (X[:, 0] / SD_F) ** 2 + (X[:, 1] / SD_F) ** 2
    out = -0.5 * r - 2.0 * math.log(SD_F) - math.log(2 * math.pi)
    out = np.where(X[:, 1] < -0.5, -np.inf, out)
    return np.where(X[:, 0] > 0.5, np.nan, out)


def test_failed_runs_are_counted_never_raised() -> None:
    prior = JointPrior({"x0": Uniform(-1.0, 1.0), "x1": Uniform(-1.0, 1.0)})
    res = run_tmcmc(loglik_with_holes, prior, n_samples=2000, seed=0)
    s0 = res.stages[0]
    assert res.status == "completed"
    assert s0.failed_runs == int(np.sum(~np.isfinite(s0.log_likelihood))) > 0
    assert not np.isnan(s0.log_likelihood).any()  # NaN stored as -inf
    assert sum(s.failed_runs for s in res.stages[1:]) > 0  # proposals into the holes
    assert res.n_failed_runs == sum(s.failed_runs for s in res.stages)
    assert np.all(res.samples[:, 0] <= 0.5) and np.all(res.samples[:, 1] >= -0.5)
    assert np.isfinite(res.log_likelihood).all()
    # exact evidence: prior density 1/4 times the Gaussian mass of the allowed rectangle
    mass0 = stats.norm.cdf(0.5 / SD_F) - stats.norm.cdf(-1.0 / SD_F)
    mass1 = stats.norm.cdf(1.0 / SD_F) - stats.norm.cdf(-0.5 / SD_F)
    log_z = math.log(0.25 * mass0 * mass1)
    assert abs(res.log_evidence - log_z) < 0.2  # 2-3 stages, measured se ~0.04


def loglik_never(X: np.ndarray) -> np.ndarray:
    return np.full(X.shape[0], np.nan)


def test_all_failed_gives_stalled_status() -> None:
    prior = JointPrior({"x": Uniform(0.0, 1.0)})
    res = run_tmcmc(loglik_never, prior, n_samples=100, seed=0)
    assert res.status == "stalled"
    assert len(res.stages) == 1
    assert res.n_failed_runs == res.n_model_runs == 100


def test_max_stages_status() -> None:
    prior = JointPrior({"x": Uniform(-1.0, 1.0)})

    def sharp(X: np.ndarray) -> np.ndarray:
        return -0.5 * (X[:, 0] / 1e-4) ** 2

    res = run_tmcmc(sharp, prior, n_samples=200, seed=0, settings=TMCMCSettings(max_stages=2))
    assert res.status == "max_stages"
    assert [s.stage for s in res.stages] == [0, 1, 2]
    assert res.stages[-1].exponent < 1.0


def test_out_of_support_proposals_are_not_evaluated() -> None:
    prior = JointPrior({"x": Uniform(0.0, 1.0)})
    seen: list[np.ndarray] = []

    def at_edge(X: np.ndarray) -> np.ndarray:
        seen.append(X.copy())
        return -0.5 * ((X[:, 0] - 1.0) / 0.05) ** 2

    res = run_tmcmc(at_edge, prior, n_samples=500, seed=1)
    pts = np.concatenate(seen)
    assert pts.min() >= 0.0 and pts.max() <= 1.0
    assert sum(s.out_of_support for s in res.stages) > 0
    assert res.n_model_runs == pts.shape[0]


def test_stage_diagnostics_are_exposed() -> None:
    prior = JointPrior({"x": Uniform(-1.0, 1.0), "y": Uniform(-1.0, 1.0)})

    def gauss(X: np.ndarray) -> np.ndarray:
        return -0.5 * ((X[:, 0] - 0.2) ** 2 + (X[:, 1] + 0.1) ** 2) / 0.05**2

    res = run_tmcmc(gauss, prior, n_samples=500, seed=0)
    rows = res.diagnostics()
    assert [r["stage"] for r in rows] == list(range(len(res.stages)))
    assert np.all(np.diff(res.exponents) > 0) and res.exponents[-1] == 1.0
    for s in res.stages[1:]:
        assert 0.0 < s.acceptance_rate < 1.0
        assert 1.0 <= s.ess <= 500.0
        assert 1 <= s.n_unique <= 500
        assert s.beta > 0.0
        assert s.model_runs == s.proposals - s.out_of_support
    assert res.log_evidence == res.stages[-1].log_evidence


def test_waste_free_chains_keep_every_state_and_cost_n_minus_m_runs() -> None:
    """Waste-free (Dau & Chopin 2022): ceil(n / P) resampled points start chains of P - 1
    moves; all P states of a chain, its start first, are samples, so a stage makes at most
    n - M model runs (out-of-support proposals are not run)."""
    from scm_core.inference import plan_stage
    from scm_core.inference.tmcmc.stage import _chain_sizes

    prior = JointPrior({"x": Uniform(-1.0, 1.0), "y": Uniform(-1.0, 1.0)})

    def gauss(X: np.ndarray) -> np.ndarray:
        return -0.5 * ((X[:, 0] - 0.2) ** 2 + (X[:, 1] + 0.1) ** 2) / 0.05**2

    n = 503  # P = 10 does not divide it: the last chain has 3 states
    settings = TMCMCSettings(moves="waste-free", n_steps=9)
    res = run_tmcmc(gauss, prior, n_samples=n, seed=0, settings=settings)
    assert res.status == "completed" and res.exponents[-1] == 1.0
    m = 51
    for prev, s in zip(res.stages[:-1], res.stages[1:], strict=True):
        plan = plan_stage(prev, prior, settings)
        assert plan.parent.shape == (m,) and plan.n_chains == m
        assert np.array_equal(plan.chain_length, [9] * 50 + [2])
        assert s.samples.shape == (n, 2) and s.n_chains == m
        # every chain's first sample is its resampled start, unchanged
        first = np.concatenate([[0], np.cumsum(plan.chain_length + 1)[:-1]])
        assert np.array_equal(s.samples[first], prev.samples[plan.parent])
        assert s.model_runs == s.proposals - s.out_of_support <= n - m
        assert np.array_equal(_chain_sizes(s, settings), [10] * 50 + [3])
    assert _chain_sizes(res.stages[0], settings) is None  # prior draws are independent
    # a rough check of the answer (the exact-answer tests are in test_inference_delayed_acceptance)
    assert abs(res.samples[:, 0].mean() - 0.2) < 0.01 and abs(res.samples[:, 1].mean() + 0.1) < 0.01


def test_evidence_variance_counts_chains_as_the_independent_units() -> None:
    from scm_core.inference.tmcmc.stage import _log_mean_weight_var

    w = np.random.default_rng(0).random(60)
    w /= w.sum()
    iid = float(np.sum(w * w)) - 1.0 / 60
    assert _log_mean_weight_var(w, None) == pytest.approx(iid, rel=1e-12)
    assert _log_mean_weight_var(w, np.ones(60, dtype=np.int64)) == pytest.approx(iid, rel=1e-12)
    # ten chains whose six states share one weight: the variance of 10 independent draws
    wc = np.repeat(w[:10] / w[:10].sum(), 6) / 6.0
    want = float(np.sum((w[:10] / w[:10].sum()) ** 2)) - 0.1
    assert _log_mean_weight_var(wc, np.full(10, 6, dtype=np.int64)) == pytest.approx(want)
    assert _log_mean_weight_var(wc, None) == pytest.approx(want / 6.0)  # iid understates it


def test_stages_stored_before_the_stagewise_sum_load_and_keep_their_error() -> None:
    """A run's dict without log_evidence_var_stagewise (stored before it was kept) loads: the
    stage-wise error is unknown (NaN; summary.json's null), the reported one is as stored."""
    from scm_core.inference import TMCMCResult

    prior = JointPrior({"x": Uniform(-1.0, 1.0)})

    def f(X: np.ndarray) -> np.ndarray:
        return -0.5 * (X[:, 0] / 0.1) ** 2

    res = run_tmcmc(f, prior, n_samples=100, seed=1)
    doc = res.to_dict()
    for stage in doc["stages"]:
        del stage["log_evidence_var_stagewise"]
    old = TMCMCResult.from_dict(doc)
    assert math.isnan(old.log_evidence_se_stagewise)
    assert old.log_evidence_se == res.log_evidence_se
    assert old.log_evidence == res.log_evidence
    assert np.array_equal(old.samples, res.samples)
