"""Is the reported standard error of log Z right? Replicate runs on exact evidences.

Two targets with an exact log Z: a 3-D linear-Gaussian one (theta ~ N(0, I), six observations
y = A theta + N(0, 0.1^2); log Z is the log density of y under N(0, s^2 I + A A^T)) and a
bimodal one (theta ~ N(0, I) in 2-D, L a mixture 0.3 N(mu, 0.2^2 I) + 0.7 N(-mu, 0.2^2 I) with
mu = (1.5, 1.5), so Z = sum_k w_k N(mu_k; 0, (1 + 0.2^2) I); the modes lie 21 component sds
apart, no chain crosses, and the mode masses rest on the stage-0 draws). The reported +-1 se
should cover the exact log Z in about 68 % of the runs; over R runs the coverage's own sd is
sqrt(0.68 * 0.32 / R) (0.074 at R = 40, 0.047 at R = 100), so the band [0.5, 0.85] lies 2.3
and 2.4 of them from 0.68 at R = 40. The sd of the errors over the rms reported se is 1 if
the errors are right, with a sampling sd of about 1 / sqrt(2 (R - 1)) (0.05 at R = 200).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy import stats

from scm_core.inference import JointPrior, TMCMCSettings, TruncatedNormal, run_tmcmc

RNG = np.random.default_rng(1)
A = RNG.normal(size=(6, 3))
S = 0.1
Y = A @ RNG.normal(size=3) + S * RNG.normal(size=6)
LOG_Z = float(stats.multivariate_normal(np.zeros(6), S * S * np.eye(6) + A @ A.T).logpdf(Y))
LOG_NORM = -0.5 * Y.size * math.log(2.0 * math.pi * S * S)

MIX_MU = np.array([[1.5, 1.5], [-1.5, -1.5]])
MIX_W = np.array([0.3, 0.7])
MIX_SD = 0.2
MIX_LOG_Z = float(
    np.logaddexp(
        *[
            math.log(w)
            + stats.multivariate_normal(np.zeros(2), (1 + MIX_SD**2) * np.eye(2)).logpdf(m)
            for w, m in zip(MIX_W, MIX_MU, strict=True)
        ]
    )
)

#: resample-move with two plain steps a stage (the CMU cases' two moves, without their
#: surrogate), systematic resampling: chains that mix slowly
SLOW = TMCMCSettings(n_steps=2)
WASTE_FREE_DA = TMCMCSettings(
    resampling="multinomial",
    moves="waste-free",
    n_steps=4,
    delayed_acceptance=True,
    surrogate_steps=10,
)


def linear_gaussian(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pred = X @ A.T
    return LOG_NORM - 0.5 * np.sum((pred - Y) ** 2, axis=1) / S**2, pred


def bimodal(X: np.ndarray) -> np.ndarray:
    parts = [
        math.log(w) + stats.multivariate_normal(m, MIX_SD**2 * np.eye(2)).logpdf(X)
        for w, m in zip(MIX_W, MIX_MU, strict=True)
    ]
    return np.logaddexp(*parts).reshape(-1)


PROBLEMS: dict[str, tuple[Callable, int, float]] = {
    "linear-gaussian": (linear_gaussian, 3, LOG_Z),
    "bimodal": (bimodal, 2, MIX_LOG_Z),
}


def replicate_errors(
    problem: str, settings: TMCMCSettings, seeds: int, n: int = 500
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(log Z-hat - log Z, reported se, stage-wise se) of runs with seeds 0..seeds-1."""
    f, d, log_z = PROBLEMS[problem]
    prior = JointPrior({f"t{j}": TruncatedNormal(0.0, 1.0, -10.0, 10.0) for j in range(d)})
    err, se, stagewise = [], [], []
    for seed in range(seeds):
        res = run_tmcmc(f, prior, n, seed=seed, settings=settings)
        err.append(res.log_evidence - log_z)
        se.append(res.log_evidence_se)
        stagewise.append(math.sqrt(res.final.log_evidence_var_stagewise))
    return np.array(err), np.array(se), np.array(stagewise)


def test_mixture_evidence_is_the_sum_of_its_components() -> None:
    """The bimodal target's exact log Z against a quadrature of prior x L on a grid."""
    g = np.linspace(-6.0, 6.0, 1201)
    X = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    prior = stats.multivariate_normal(np.zeros(2), np.eye(2)).logpdf(X)
    z = np.sum(np.exp(prior + bimodal(X))) * (g[1] - g[0]) ** 2
    assert math.log(z) == pytest.approx(MIX_LOG_Z, abs=1e-6)


@pytest.mark.parametrize("problem", list(PROBLEMS))
def test_slowly_mixing_runs_report_errors_that_cover_the_exact_evidence(problem: str) -> None:
    """Chains of two steps carry each stage's error into the next: the stage-wise sum covers
    log Z in about a third of 100 runs (0.31 linear-Gaussian, 0.33 bimodal), the genealogy
    estimate in 0.69 and 0.61 of them; here 40 seeds (0.65 and 0.65)."""
    err, se, stagewise = replicate_errors(problem, SLOW, 40)
    cover = float(np.mean(np.abs(err) <= se))
    print(f"{problem}: coverage {cover:.2f}, stage-wise {np.mean(np.abs(err) <= stagewise):.2f}")
    assert 0.5 <= cover <= 0.85
    assert np.mean(np.abs(err) <= stagewise) < 0.5


@pytest.mark.slow
@pytest.mark.parametrize("problem", list(PROBLEMS))
@pytest.mark.parametrize(
    "settings",
    [
        TMCMCSettings(),
        TMCMCSettings(resampling="multinomial"),
        TMCMCSettings(n_steps=2, resampling="multinomial"),
        WASTE_FREE_DA,
        TMCMCSettings(moves="waste-free", n_steps=4, delayed_acceptance=True, surrogate_steps=10),
    ],
    ids=["resample-move", "resample-move-mult", "slow-mult", "waste-free-da-mult", "waste-free-da"],
)
def test_reported_errors_cover_the_exact_evidence(problem: str, settings: TMCMCSettings) -> None:
    """Coverage of +-1 reported se over 100 seeds within [0.5, 0.85] for every form (measured
    0.59-0.77, and 0.84 for systematic waste-free on the bimodal target, whose error is on the
    safe side: sd / se 0.81 on the bench's table, docs/calibration.md)."""
    err, se, _ = replicate_errors(problem, settings, 100)
    cover = float(np.mean(np.abs(err) <= se))
    print(f"{problem}: coverage {cover:.2f}")
    assert 0.5 <= cover <= 0.85


@pytest.mark.slow
@pytest.mark.parametrize(
    "settings",
    [TMCMCSettings(), TMCMCSettings(resampling="multinomial"), WASTE_FREE_DA],
    ids=["resample-move", "resample-move-mult", "waste-free-da-mult"],
)
def test_reported_evidence_errors_match_the_spread_over_runs(settings: TMCMCSettings) -> None:
    """sd of the errors over 200 runs of 500 samples against the rms reported se: the band
    [0.75, 1.2] allows 4 sampling sds above 1 and the conservative side of the estimate
    (measured 1.01, 1.00, 0.89); the stage-wise sum alone gave 1.27 (systematic) there."""
    err, se, _ = replicate_errors("linear-gaussian", settings, 200)
    ratio = err.std(ddof=1) / math.sqrt(np.mean(se**2))
    print(f"sd {err.std(ddof=1):.3f}, rms se {math.sqrt(np.mean(se**2)):.3f}, ratio {ratio:.2f}")
    assert 0.75 < ratio < 1.2
    # and the errors are unbiased at this size: mean error within 3 standard errors of 0
    assert abs(err.mean()) < 3.0 * err.std(ddof=1) / math.sqrt(err.size)
