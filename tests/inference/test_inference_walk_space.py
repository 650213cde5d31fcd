"""The random walk in log coordinates (``proposal_scale = "log"``) against exact answers.

A log walk is exact only with its proposal ratio, log q(x | x') - log q(x' | x) =
sum (log x'_j - log x_j) over the log columns. Without it the chains would target pi(x) / prod x_j:
on the log-normal conjugate target below that shifts the posterior mean of log theta by
-tau^2 = -0.45 tau (tau the posterior sd of log theta), which the 0.1 tau tolerance catches.
Tolerances and Monte Carlo budgets as in test_inference_tmcmc_accuracy (2000 samples).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from parted_targets import A5, S5, Y5, PartedLinearGaussian, exact_linear
from scipy import stats

from scm_core.inference import JointPrior, TMCMCSettings, TruncatedNormal, run_tmcmc
from scm_core.inference.priors import LogNormal
from scm_core.inference.walk_space import (
    from_walk,
    log_columns,
    log_proposal_ratio,
    to_walk,
)

# --- log-normal prior, Gaussian datum on log theta: conjugate in u = log theta ---------------

M0, F0 = 2.0, math.e  # prior median and geometric sd: log theta ~ N(log 2, 1)
Y_LOG, S_LOG = 1.5, 0.5  # datum on log theta and its noise sd


def loglik_lognormal(X: np.ndarray) -> np.ndarray:
    r = (np.log(X[:, 0]) - Y_LOG) / S_LOG
    return -0.5 * r * r - math.log(S_LOG) - 0.5 * math.log(2 * math.pi)


@pytest.mark.parametrize("moves", ["resample-move", "waste-free"])
def test_log_walk_lognormal_conjugate(moves: str) -> None:
    # truncated at +-20 prior sd in log theta: negligible mass
    prior = JointPrior({"theta": LogNormal(M0, F0, M0 * F0**-20, M0 * F0**20)})
    # P = 10 states per waste-free chain
    settings = TMCMCSettings(
        moves=moves, proposal_scale="log", n_steps=9 if moves == "waste-free" else None
    )
    assert log_columns(prior, "log").tolist() == [True]
    res = run_tmcmc(loglik_lognormal, prior, 2000, seed=0, settings=settings)
    post_mean, tau, log_z = exact_lognormal()
    u = np.log(res.samples[:, 0])
    print(
        f"log walk {moves}: mean err/sd {(u.mean() - post_mean) / tau:+.3f}, sd rel err "
        f"{u.std() / tau - 1:+.3f}, log Z err {res.log_evidence - log_z:+.3f}"
    )
    assert res.status == "completed"
    assert abs(u.mean() - post_mean) < 0.1 * tau
    assert abs(u.std() / tau - 1.0) < 0.10
    assert abs(res.log_evidence - log_z) < 0.25


# --- the 5-D linear-Gaussian target moved to positive support ------------------------------

SHIFT = 3.0
#: N(3, 1) per axis truncated to [0.01, 13]: strictly positive support, so every column walks in log
PRIOR_SHIFTED = JointPrior(
    {f"t{j}": TruncatedNormal(SHIFT, 1.0, 0.01, SHIFT + 10.0) for j in range(5)}
)


def exact_shifted() -> tuple[np.ndarray, np.ndarray, float]:
    """Posterior mean, sd and log evidence of the 5-D target moved by SHIFT."""
    mean, sd, log_z = exact_linear(A5, Y5, S5)
    return SHIFT + mean, sd, log_z


def exact_lognormal() -> tuple[float, float, float]:
    """Posterior mean and sd of log theta and the log evidence of the log-normal target."""
    mu0 = math.log(M0)
    post_var = 1.0 / (1.0 + 1.0 / S_LOG**2)
    log_z = stats.norm.logpdf(Y_LOG, mu0, math.sqrt(1.0 + S_LOG**2))
    return post_var * (mu0 + Y_LOG / S_LOG**2), math.sqrt(post_var), float(log_z)


def loglik_shifted(X: np.ndarray) -> np.ndarray:
    total = np.zeros(X.shape[0])
    for i in range(A5.shape[0]):
        pred = np.zeros(X.shape[0])
        for j in range(A5.shape[1]):
            pred = pred + A5[i, j] * (X[:, j] - SHIFT)
        r = (Y5[i] - pred) / S5
        total = total - 0.5 * r * r
    return total - A5.shape[0] * (math.log(S5) + 0.5 * math.log(2 * math.pi))


def test_log_walk_linear_gaussian_5d_on_positive_support() -> None:
    """Gaussian in x, so curved in the walk's log coordinates: still exact (prior N(3, 1)
    truncated to [0.01, 13]: the lower cut is 3 sd out, mass 1.4e-3 per axis, and the
    likelihood puts the posterior ~0.1 from 3, so the truncation is immaterial)."""
    assert log_columns(PRIOR_SHIFTED, "log").all()
    res = run_tmcmc(
        loglik_shifted, PRIOR_SHIFTED, 2000, seed=0, settings=TMCMCSettings(proposal_scale="log")
    )
    mean, sd, log_z = exact_shifted()
    err_mean = np.abs(res.samples.mean(axis=0) - mean) / sd
    err_sd = np.abs(res.samples.std(axis=0) / sd - 1.0)
    print(
        f"5-D log walk: mean err/sd {err_mean.max():.3f}, sd rel err {err_sd.max():.3f}, "
        f"log Z err {res.log_evidence - log_z:+.3f}"
    )
    assert res.status == "completed"
    assert err_mean.max() < 0.1 and err_sd.max() < 0.10
    corr = np.linalg.inv(np.eye(5) + A5.T @ A5 / S5**2) / np.outer(sd, sd)
    assert np.abs(np.corrcoef(res.samples, rowvar=False) - corr).max() < 0.05
    assert abs(res.log_evidence - log_z) < 0.25


# --- the coordinates themselves -------------------------------------------------------------


def test_walk_coordinates_and_proposal_ratio() -> None:
    prior = JointPrior(
        {
            "k": LogNormal(1e6, 2.0, 1e3, 1e9),
            "c": TruncatedNormal(0.0, 1.0, -5.0, 5.0),
            "s": TruncatedNormal(1.0, 1.0, 0.0, 5.0),  # lower bound 0: not strictly positive
        }
    )
    logs = log_columns(prior, "log")
    assert logs.tolist() == [True, False, False]
    assert not log_columns(prior, "linear").any()
    with pytest.raises(ValueError, match="proposal_scale"):
        log_columns(prior, "sqrt")
    X = np.array([[2e6, -0.5, 0.3], [5e5, 1.0, 2.0]])
    U = to_walk(X, logs)
    assert np.allclose(from_walk(U, logs), X, rtol=1e-15)
    X2 = X * np.array([[3.0, 1.0, 1.0], [0.5, 1.0, 1.0]]) + np.array([[0, 0.2, 0.1], [0, 0, 0]])
    # q(x | x') / q(x' | x) for a symmetric walk in log k: x'_k / x_k
    assert np.allclose(log_proposal_ratio(to_walk(X2, logs), U, logs), np.log([3.0, 0.5]))
    with pytest.raises(ValueError, match="proposal_scale"):
        TMCMCSettings(proposal_scale="sqrt")


def test_log_walk_is_batch_invariant() -> None:
    prior = JointPrior({"theta": LogNormal(M0, F0, M0 * F0**-20, M0 * F0**20)})
    settings = TMCMCSettings(proposal_scale="log")
    one = run_tmcmc(loglik_lognormal, prior, 200, seed=3, settings=settings, batch_size=None)
    many = run_tmcmc(loglik_lognormal, prior, 200, seed=3, settings=settings, batch_size=7)
    assert one.samples.tobytes() == many.samples.tobytes()
    assert one.log_evidence == many.log_evidence


# --- with surrogate transitions in waste-free chains (the accelerated form of issue 12) ------


class LogNormalWithResponse:
    """The log-normal conjugate target with its response log theta exposed (the surrogate
    interpolates it)."""

    response_inputs = (0,)

    def from_responses(self, X: np.ndarray, R: np.ndarray):
        r = (R[:, 0] - Y_LOG) / S_LOG
        return -0.5 * r * r - math.log(S_LOG) - 0.5 * math.log(2 * math.pi), R

    def __call__(self, X: np.ndarray):
        return self.from_responses(X, np.log(X[:, :1]))


@pytest.mark.slow
@pytest.mark.parametrize("states", [5, 10])
def test_log_walk_with_surrogate_transitions_in_waste_free_chains(states: int) -> None:
    """Waste-free chains of P states whose moves are surrogate transitions (K = 10 inner steps,
    each with the proposal ratio) on both targets: the log-normal conjugate (tolerances as
    above) and the 5-D linear-Gaussian target on positive support with its responses."""
    settings = TMCMCSettings(
        moves="waste-free",
        n_steps=states - 1,
        delayed_acceptance=True,
        surrogate_steps=10,
        proposal_scale="log",
    )
    prior = JointPrior({"theta": LogNormal(M0, F0, M0 * F0**-20, M0 * F0**20)})
    res = run_tmcmc(LogNormalWithResponse(), prior, 2000, seed=0, settings=settings)
    post_mean, tau, log_z = exact_lognormal()
    u = np.log(res.samples[:, 0])
    screened = sum(s.first_stage_rejections for s in res.stages)
    print(
        f"log walk wf P={states} DA: mean err/sd {(u.mean() - post_mean) / tau:+.3f}, sd rel "
        f"err {u.std() / tau - 1:+.3f}, log Z err {res.log_evidence - log_z:+.3f}, "
        f"screened {screened}"
    )
    # the surrogate was really used: ten inner steps per model run, checked at every run
    assert sum(s.surrogate_steps for s in res.stages) >= 10 * (res.n_model_runs - 2000)
    assert sum(s.surrogate_checks for s in res.stages) > 0
    assert abs(u.mean() - post_mean) < 0.1 * tau
    assert abs(u.std() / tau - 1.0) < 0.10
    assert abs(res.log_evidence - log_z) < 0.25

    f = PartedLinearGaussian(A5, Y5 + A5 @ np.full(5, SHIFT), S5, [(0, 1), (2, 3), (4, 5), (6, 7)])
    res = run_tmcmc(f, PRIOR_SHIFTED, 2000, seed=0, settings=settings)
    mean, sd, log_z = exact_shifted()
    err_mean = np.abs(res.samples.mean(axis=0) - mean) / sd
    err_sd = np.abs(res.samples.std(axis=0) / sd - 1.0)
    screened = sum(s.first_stage_rejections for s in res.stages)
    print(
        f"5-D log walk wf P={states} DA: mean err/sd {err_mean.max():.3f}, sd err "
        f"{err_sd.max():.3f}, log Z err {res.log_evidence - log_z:+.3f}, runs "
        f"{res.n_model_runs}, screened {screened}"
    )
    assert screened > 0
    assert err_mean.max() < 0.1 and err_sd.max() < 0.10
    assert abs(res.log_evidence - log_z) < 0.25
