"""Delayed acceptance with a response surrogate (issue 12) against targets with exact answers.

Delayed acceptance changes the chains (a proposal the surrogate turns down is not simulated), so
unlike early rejection it is checked against the exact answers, with the tolerances of
test_inference_tmcmc_accuracy and test_inference_update (their docstrings give the Monte Carlo
error budgets), on test likelihoods whose output follows from responses, so the surrogate is
really used: every test asserts that the surrogate turned proposals down. Each runs with one
inner step (Christen & Fox's delayed acceptance), with ten (a surrogate transition, Liu 2001),
in the accelerated accurate form (waste-free chains, Dau & Chopin 2022: every chain state is a
sample; 40 inner steps, log walk, multinomial resampling), and with population jumps.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from parted_targets import (
    A5,
    PRIOR5,
    S5,
    Y5,
    PartedBimodal,
    PartedLinearGaussian,
    exact_linear,
    parted_5d,
    update_problem,
)
from scipy import stats

from scm_core.inference import (
    JointPrior,
    PopulationStart,
    TMCMCSettings,
    TruncatedNormal,
    Uniform,
    run_tmcmc,
)
from scm_core.inference.tmcmc.moves import form_defaults


@pytest.fixture(
    params=[
        pytest.param((1, "resample-move", 0.0), marks=pytest.mark.slow),
        pytest.param((10, "resample-move", 0.0), marks=pytest.mark.slow),
        pytest.param((None, "waste-free", 0.0), marks=pytest.mark.slow),
        (10, "waste-free", 0.5),
    ],
    ids=["da", "stm10", "waste-free-default", "wf-stm10-jumps"],
)
def da(request) -> TMCMCSettings:
    """Delayed acceptance with 1 or 10 surrogate steps per model run in resample-move chains;
    the accelerated accurate form a case gets with ``moves = "waste-free"`` (chains of P = 5
    states, surrogate transitions of 40 steps of which a fifth are population jumps, log walk,
    multinomial resampling); and
    waste-free chains of P = 10 states with 10 surrogate steps, half of them population jumps
    (independence proposals)."""
    steps, moves, jumps = request.param
    if steps is None:
        return TMCMCSettings(moves=moves, **form_defaults(moves))
    return TMCMCSettings(
        delayed_acceptance=True,
        surrogate_steps=steps,
        moves=moves,
        surrogate_jumps=jumps,
        n_steps=9 if moves == "waste-free" else None,
    )


def _jumped(res, settings: TMCMCSettings) -> bool:
    """With population jumps on, some were proposed and some accepted."""
    if settings.surrogate_jumps == 0.0:
        return all(s.population_jumps == 0 for s in res.stages)
    return sum(s.population_jumps_accepted for s in res.stages) > 0


def _screened(res) -> int:
    """Surrogate steps inside the support that the model never saw (one inner step: the
    proposals the screen turned down)."""
    return sum(s.surrogate_steps - s.out_of_support - s.model_runs for s in res.stages[1:])


@pytest.mark.slow  # the heaviest; the 1-D, bimodal, curved and update checks stay fast
def test_linear_gaussian_5d_exact_answer_with_fewer_model_runs(da: TMCMCSettings) -> None:
    f = parted_5d()
    plain = run_tmcmc(f, PRIOR5, seed=0, settings=TMCMCSettings(early_rejection=False))
    res = run_tmcmc(f, PRIOR5, seed=0, settings=da)
    mean, sd, log_z = exact_linear(A5, Y5, S5)
    err_mean = np.abs(res.samples.mean(axis=0) - mean) / sd
    err_sd = np.abs(res.samples.std(axis=0) / sd - 1.0)
    checks = sum(s.surrogate_checks for s in res.stages)
    err = sum(s.surrogate_error_sum for s in res.stages) / max(checks, 1)
    print(
        f"5-D DA: mean err/sd {err_mean.max():.3f}, sd err {err_sd.max():.3f}, log Z err "
        f"{res.log_evidence - log_z:+.3f}; model runs {plain.n_model_runs} -> "
        f"{res.n_model_runs}, screened {_screened(res)}, surrogate |error| {err:.2e}"
    )
    assert res.status == "completed"
    assert _screened(res) > 0 and checks > 0 and _jumped(res, da)
    # 0.1 sd, 10 %, 0.25 nat: the tolerances of test_linear_gaussian_5d
    assert err_mean.max() < 0.1
    assert err_sd.max() < 0.10
    assert abs(res.log_evidence - log_z) < 0.25
    # the surrogate reproduces a linear model (thin-plate spline with a linear term), so the
    # screen turns down what the model would and the model runs fall by more than half
    assert res.n_model_runs < 0.5 * plain.n_model_runs


def test_conjugate_1d_exact_answer(da: TMCMCSettings) -> None:
    A, y, s = np.array([[1.0], [1.0]]), np.array([0.52, 0.48]), 0.01 * math.sqrt(2.0)
    prior = JointPrior({"theta": TruncatedNormal(0.0, 1.0, -20.0, 20.0)})
    res = run_tmcmc(PartedLinearGaussian(A, y, s, [(0,), (1,)]), prior, seed=0, settings=da)
    mean, sd, log_z = exact_linear(A, y, s)
    assert _screened(res) > 0 and _jumped(res, da)
    assert abs(res.samples[:, 0].mean() - mean[0]) < 0.1 * sd[0]
    assert abs(res.samples[:, 0].std() / sd[0] - 1.0) < 0.10
    assert abs(res.log_evidence - log_z) < 0.25


def test_bimodal_product_mode_masses_and_evidence(da: TMCMCSettings) -> None:
    """The surrogate interpolates a bimodal log-density (not reproduced exactly)."""
    prior = JointPrior({f"x{j}": Uniform(-5.0, 5.0) for j in range(4)})
    res = run_tmcmc(PartedBimodal(), prior, seed=0, settings=da)
    assert res.status == "completed" and _screened(res) > 0 and _jumped(res, da)
    assert abs(res.log_evidence + 4.0 * math.log(10.0)) < 0.3
    for k in range(2):
        assert abs(np.mean(res.samples[:, 2 * k : 2 * k + 2].sum(axis=1) < 0.0) - 0.1) < 0.05


def test_posterior_piled_against_bound(da: TMCMCSettings) -> None:
    mu, sd = 1.2, 0.3
    f = PartedLinearGaussian(
        np.array([[1.0], [1.0]]), np.array([mu, mu]), sd * math.sqrt(2.0), [(0,), (1,)]
    )
    res = run_tmcmc(f, JointPrior({"theta": Uniform(0.0, 1.0)}), seed=0, settings=da)
    exact = stats.truncnorm((0.0 - mu) / sd, (1.0 - mu) / sd, loc=mu, scale=sd)
    assert _screened(res) > 0 and _jumped(res, da)
    assert abs(res.samples[:, 0].mean() - exact.mean()) < 0.1 * exact.std()
    assert stats.kstest(res.samples[:, 0], exact.cdf).statistic < 0.05


def test_update_with_surrogate_and_early_rejection_exact_answer(da: TMCMCSettings) -> None:
    """As test_inference_update, with both accelerations on (4000 samples: 0.1 sd, 7 %,
    0.2 nat, as test_update_with_base_parts_same_bits_and_exact_answer)."""
    prior, old_f, f, A, y, s = update_problem()
    old = run_tmcmc(old_f, prior, 4000, seed=3)
    res = run_tmcmc(f, prior, 4000, seed=4, settings=da, start=PopulationStart(old.samples))
    mean, sd, log_z = exact_linear(A, y, s)
    assert _screened(res) > 0 and _jumped(res, da)
    assert np.all(np.abs(res.samples.mean(axis=0) - mean) < 0.1 * sd)
    assert np.all(np.abs(res.samples.std(axis=0) / sd - 1.0) < 0.07)
    assert abs(old.log_evidence + res.log_evidence - log_z) < 0.2


@pytest.mark.parametrize("steps", [1, pytest.param(10, marks=pytest.mark.slow)])
@pytest.mark.parametrize("moves", ["resample-move", "leader", "waste-free", "waste-free-jumps"])
def test_batches_do_not_change_results(moves: str, steps: int) -> None:
    """The surrogate is a function of the stage plan: any batch split gives the same bits."""
    f = parted_5d()
    jumps = 0.5 if moves.endswith("-jumps") else 0.0
    settings = TMCMCSettings(
        delayed_acceptance=True,
        surrogate_steps=steps,
        moves=moves.removesuffix("-jumps"),
        surrogate_jumps=jumps,
    )
    a = run_tmcmc(f, PRIOR5, 200, seed=2, settings=settings)
    b = run_tmcmc(f, PRIOR5, 200, seed=2, settings=settings, batch_size=37)
    assert _screened(a) > 0
    for sa, sb in zip(a.stages, b.stages, strict=True):
        np.testing.assert_array_equal(sa.samples, sb.samples)
        np.testing.assert_array_equal(sa.log_likelihood, sb.log_likelihood)
        assert sa.log_evidence == sb.log_evidence
        assert sa.first_stage_rejections == sb.first_stage_rejections
        assert sa.surrogate_error_sum == sb.surrogate_error_sum


# --- a curved target the surrogate cannot reproduce (evidence by quadrature) -----------------

Y_B, S_B = np.array([0.6, 0.3]), np.array([0.05, 0.04])


class Banana:
    """Responses r(theta) = (sin 2 a + b^2, a b), data Y_B with sd S_B, theta ~ U(-2, 2)^2:
    a curved, two-branch posterior; the surrogate interpolates r with errors (~0.7 nat)."""

    response_inputs = (0, 1)

    def from_responses(self, X: np.ndarray, R: np.ndarray):
        r = (Y_B - R) / S_B
        ll = -0.5 * (r[:, 0] ** 2 + r[:, 1] ** 2) - np.log(S_B).sum() - math.log(2 * math.pi)
        return ll, R

    def __call__(self, X: np.ndarray):
        R = np.stack([np.sin(2 * X[:, 0]) + X[:, 1] ** 2, X[:, 0] * X[:, 1]], axis=1)
        return self.from_responses(X, R)


def test_curved_target_with_an_imperfect_surrogate_keeps_the_evidence(da: TMCMCSettings) -> None:
    """Quadrature on a 4001^2 grid gives log Z (its error is far below 0.01). Over six seeds
    at 1000 samples the error of log Z had sd 0.08 with the screen (0.16 without), mean -0.003;
    0.3 nat is ~4 sd. The screen saves ~4/5 of the model runs here."""
    g = np.linspace(-2.0, 2.0, 4001)
    G0, G1 = np.meshgrid(g, g, indexing="ij")
    ll, _ = Banana()(np.stack([G0.ravel(), G1.ravel()], axis=1))
    log_z = float(np.logaddexp.reduce(ll) + 2 * math.log(g[1] - g[0]) - 2 * math.log(4.0))
    prior = JointPrior({"a": Uniform(-2.0, 2.0), "b": Uniform(-2.0, 2.0)})
    # trained on the starting states only (the carried training set makes it nearly exact)
    res = run_tmcmc(
        Banana(), prior, 1000, seed=2, settings=dataclasses.replace(da, surrogate_memory=0)
    )
    checks = sum(s.surrogate_checks for s in res.stages)
    error = sum(s.surrogate_error_sum for s in res.stages) / checks
    assert _screened(res) > res.n_model_runs  # most proposals never reached the model
    assert _jumped(res, da)
    assert error > 0.1  # the surrogate is really imperfect here
    assert abs(res.log_evidence - log_z) < 0.3


def test_surrogate_is_scipys_local_thin_plate_spline_row_by_row() -> None:
    """The surrogate's interpolant is scipy's ``RBFInterpolator`` (thin-plate spline, linear
    term, 50 neighbours, smoothing) to rounding, and a row's prediction is the same bytes
    alone, in any batch or chunk (the reason it is computed here and not by scipy)."""
    from scipy.interpolate import RBFInterpolator

    from scm_core.inference.surrogate import CHUNK, fit_surrogate

    rng = np.random.default_rng(3)
    X = rng.normal(size=(400, 4))
    R = np.column_stack([np.sin(X[:, 0]) + X[:, 1] ** 2, X[:, 2] * X[:, 3], np.exp(X[:, 0] / 3)])
    X[5] = X[4]  # a repeated state is fitted once
    surrogate = fit_surrogate(X, R, (0, 1, 2, 3), neighbors=50, smoothing=1e-3)
    assert surrogate is not None and surrogate.n_points == 399
    Q = rng.normal(size=(CHUNK + 44, 4))
    mine = surrogate.predict(Q)
    keep = np.sort(np.unique(X, axis=0, return_index=True)[1])
    U = (X[keep] - surrogate.center) / surrogate.scale
    V = (R[keep] - surrogate.y_center) / surrogate.y_scale
    scipy_rbf = RBFInterpolator(
        U, V, neighbors=50, kernel="thin_plate_spline", degree=1, smoothing=1e-3
    )
    ref = scipy_rbf((Q - surrogate.center) / surrogate.scale) * surrogate.y_scale
    ref += surrogate.y_center
    np.testing.assert_allclose(mine, ref, rtol=1e-10, atol=1e-10)
    for i in (0, 17, CHUNK, CHUNK + 43):
        assert np.array_equal(surrogate.predict(Q[i : i + 1])[0], mine[i])
    assert np.array_equal(surrogate.predict(Q[9:]), mine[9:])  # other chunk boundaries


def test_surrogate_fits_only_the_responses_the_likelihood_reads() -> None:
    """``outputs``: the columns the likelihood reads are fitted, to the same bytes as when
    every column is (each column's system is its own); the others are predicted NaN and
    need not be finite in the training states (a response a stored study did not carry)."""
    from scm_core.inference.surrogate import fit_surrogate

    rng = np.random.default_rng(5)
    X = rng.normal(size=(120, 3))
    R = np.column_stack([X[:, 0] ** 2, np.nan * X[:, 1], np.cos(X[:, 2]), X[:, 0] * X[:, 1]])
    R[:40, 3] = np.nan  # the fourth column carried by some states only
    full = fit_surrogate(X[40:], R[40:][:, [0, 2, 3]], (0, 1, 2), neighbors=30, smoothing=1e-3)
    some = fit_surrogate(X, R, (0, 1, 2), neighbors=30, smoothing=1e-3, outputs=(0, 2))
    assert full is not None and some is not None and some.n_points == 120
    Q = rng.normal(size=(50, 3))
    got = some.predict(Q)
    assert got.shape == (50, 4) and np.isnan(got[:, [1, 3]]).all()
    alone = fit_surrogate(X, R[:, [0, 2]], (0, 1, 2), neighbors=30, smoothing=1e-3)
    assert got[:, [0, 2]].tobytes() == alone.predict(Q).tobytes()
    assert np.isfinite(full.predict(Q)).all()
    # without outputs a state with any non-finite response is left out, as before
    assert fit_surrogate(X, R, (0, 1, 2), neighbors=30, smoothing=1e-3) is None
