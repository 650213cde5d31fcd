"""The tempering arithmetic of a TMCMC stage (Ching & Chen 2007): plausibility weights and the
next exponent from their coefficient of variation, systematic or multinomial resampling, the log
evidence's variance from the population's genealogy, the weighted sample covariance and its
Cholesky factor for the proposal, and the adaptation of the proposal scale. Pure functions of
arrays."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.inference import portable

if TYPE_CHECKING:
    from scm_core.inference.tmcmc.types import TMCMCSettings

__all__ = [
    "adapt_beta",
    "genealogy_log_evidence_var",
    "multinomial_resample",
    "next_exponent",
    "plausibility_weights",
    "proposal_factor",
    "systematic_resample",
    "weighted_covariance",
]


def plausibility_weights(
    log_likelihood: NDArray[np.float64], delta_p: float
) -> tuple[NDArray[np.float64], float]:
    """Normalised weights w_i ∝ L_i^delta_p and log mean of the unnormalised weights.

    Computed in log space; samples with log L = -inf get weight 0 (for delta_p > 0). Returns
    (weights (n,), log mean w) where log mean w is the evidence increment log(S_j) of Ching & Chen.
    """
    ll = np.asarray(log_likelihood, dtype=float)
    finite = np.isfinite(ll)
    if not finite.any():
        raise ValueError("all log-likelihoods are -inf: no plausibility weights")
    a = np.where(finite, delta_p * np.where(finite, ll, 0.0), -np.inf)
    lse = portable.logsumexp(a)
    w = portable.exp(a - lse)
    return w, float(lse - math.log(ll.shape[0]))


def _weights_cov(a_finite: NDArray[np.float64], n: int) -> float:
    """Coefficient of variation of exp(a) over n samples, of which len(a_finite) are nonzero."""
    w = portable.exp(a_finite - a_finite.max())
    mean = w.sum() / n
    second = (w * w).sum() / n
    var = max(second - mean * mean, 0.0)
    return math.sqrt(var) / mean


def next_exponent(log_likelihood: ArrayLike, p_prev: float, target_cov: float = 1.0) -> float:
    """Next tempering exponent p in (p_prev, 1] (Ching & Chen 2007, eq. for p_{j+1}).

    Bisection on delta = p - p_prev so that the coefficient of variation (population std / mean)
    of the weights w_i = exp(delta * log L_i) equals ``target_cov``; capped at 1. Samples with
    log L = -inf get weight 0 for any delta > 0. If those zeros alone already push the CoV to the
    target (half or more of the samples failed, for target 1), the CoV is taken over the finite
    samples only, so that the step still makes progress. Deterministic.
    """
    ll = np.asarray(log_likelihood, dtype=float)
    finite = ll[np.isfinite(ll)]
    if finite.size == 0:
        raise ValueError("all log-likelihoods are -inf: cannot choose the next exponent")
    n = ll.shape[0]
    if math.sqrt(n / finite.size - 1.0) >= target_cov:
        n = finite.size
    hi = 1.0 - p_prev
    if hi <= 0:
        return 1.0
    if _weights_cov(hi * finite, n) <= target_cov:
        return 1.0
    lo = 0.0
    for _ in range(500):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if _weights_cov(mid * finite, n) > target_cov:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 1e-13 * hi:
            break
    return min(p_prev + hi, 1.0)


def _pick(weights: ArrayLike, positions: NDArray[np.float64]) -> NDArray[np.int64]:
    """Indices whose cumulative-weight intervals hold the sorted ``positions`` in [0, 1)."""
    w = np.asarray(weights, dtype=float)
    cw = np.cumsum(w)
    cw /= cw[-1]
    cw[-1] = 1.0
    idx = np.searchsorted(cw, positions, side="right")
    return np.minimum(idx, w.shape[0] - 1).astype(np.int64)


def systematic_resample(weights: ArrayLike, n: int, rng: np.random.Generator) -> NDArray[np.int64]:
    """Systematic resampling: n sorted indices, index i drawn ~ n * w_i times (±1)."""
    return _pick(weights, (rng.random() + np.arange(n)) / n)


def multinomial_resample(weights: ArrayLike, n: int, rng: np.random.Generator) -> NDArray[np.int64]:
    """Multinomial resampling: n independent draws of an index with probabilities ``weights``,
    sorted (Ching & Chen's TMCMC draws the next stage's seeds this way). Independent draws are
    what Lee & Whiteley's correction in :func:`genealogy_log_evidence_var` assumes; after
    systematic resampling, which has less variance of its own, that function leaves it out
    (``bench_evidence_error.py``, docs/calibration.md)."""
    return _pick(weights, np.sort(rng.random(n)))


#: the resampling schemes (TMCMCSettings.resampling names one): the one declaration of their
#: names
RESAMPLERS = {"systematic": systematic_resample, "multinomial": multinomial_resample}


def genealogy_log_evidence_var(
    weights: NDArray[np.float64],
    eve: NDArray[np.int64],
    n_weightings: int,
    first_draws: int,
    draws: int,
    resampling: str = "multinomial",
) -> float:
    """Var(log Z-hat) after ``n_weightings`` weightings, from the population's genealogy.

    Lee & Whiteley (2018, Biometrika 105(3), eq. 4) estimate Var(Z-hat) / Z-hat^2 from one run
    of a particle system with multinomial resampling as 1 - f (1 - sum_e W_e^2): W_e sums the
    normalised weights of the last weighting over the particles that descend from initial
    particle e (their Eve), f = prod_t N_t / (N_t - 1) over the weightings, N_t the independent
    draws behind the population weighted at t. Du & Guyader (2021, Ann. Appl. Probab. 31(3))
    show it consistent when the tempering exponents are chosen from the particles, as here.
    Unlike a sum of per-stage terms it counts the correlation that resampling and slowly mixing
    chains carry from one stage to the next: a stage-0 draw and all its descendants are one
    cluster. The first weighting acts on ``first_draws`` stage-0 draws, every later one on a
    population resampled with ``draws`` draws (n for resample-move and leader; the M chain
    starts of waste-free, whose chains are its particles: Dau & Chopin 2022, section 3).

    The factors N_t / (N_t - 1) of the later weightings remove the spread that multinomial
    resampling's own noise adds to the W_e. Systematic resampling (``resampling =
    "systematic"``) gives each particle its expected number of offspring to within one, so it
    adds almost none and f is the first factor alone: the estimate is then the iid formula over
    the stage-0 clusters, (N_0 sum_e W_e^2 - 1) / (N_0 - 1) ~ sum_e (W_e - 1 / N_0)^2 (the sum
    over all N_0 Eves). With the multinomial f it comes out 1.5 times too small there in sd,
    and negative for waste-free; without it, within 0.8-1.1 times the replicates' spread on the
    exact targets of ``bench_evidence_error.py``. Var(log Z-hat) ~ Var(Z-hat) / Z^2 (delta
    method). When the lineages have coalesced to a few Eves it rests on those few clusters and
    comes out too small (1.6 times in sd at a median of ten Eves, the slow 5-D runs there); at
    one Eve it is 1, a relative error of order one, and cannot say more. Can be negative when
    small against its own noise.
    """
    w_eve = np.bincount(np.asarray(eve, dtype=np.int64), weights=np.asarray(weights, float))
    s = float(np.sum((w_eve / w_eve.sum()) ** 2))
    log_f = math.log(first_draws / (first_draws - 1.0))
    if resampling == "multinomial":
        log_f += (n_weightings - 1) * math.log(draws / (draws - 1.0))
    elif resampling != "systematic":
        raise ValueError(f"unknown resampling {resampling!r}")
    return 1.0 - math.exp(log_f) * (1.0 - s)


def weighted_covariance(X: ArrayLike, weights: ArrayLike) -> NDArray[np.float64]:
    """Sum_i w_i (x_i - m)(x_i - m)^T with m = sum_i w_i x_i (weights normalised to sum to 1),
    in a fixed order (:mod:`scm_core.inference.portable`: the same bits on every CPU)."""
    X = np.ascontiguousarray(X, dtype=float)
    w = np.asarray(weights, dtype=float)
    return portable.weighted_covariance(X, np.ascontiguousarray(w / w.sum()))


def proposal_factor(
    cov: NDArray[np.float64], bounds: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Add a tiny diagonal jitter (1e-10 relative + 1e-20 of the prior range squared) and factor.

    The jitter keeps degenerate dimensions (all samples equal) movable; it is increased tenfold
    until the Cholesky factorisation succeeds.
    """
    d = cov.shape[0]
    span2 = (bounds[:, 1] - bounds[:, 0]) ** 2
    diag = np.clip(np.diag(cov), 0.0, None)
    jitter = 1e-10 * diag + 1e-20 * span2
    for _ in range(30):
        c = cov + np.diag(jitter)
        try:
            return c, portable.cholesky(c)
        except np.linalg.LinAlgError:
            jitter = jitter * 10.0 + 1e-300
    raise np.linalg.LinAlgError(f"proposal covariance not positive definite (d={d})")


def adapt_beta(beta: float, acceptance_rate: float, settings: TMCMCSettings) -> float:
    """Proposal-scale update after a stage: beta * exp(gain * (acc - target)), clipped.

    Stochastic-approximation form (log beta moves by gain * (acceptance - target)); with the
    default target 0.234 (Roberts, Gelman & Gilks 1997, optimal random-walk acceptance for
    moderate to high dimension) it replaces Ching & Chen's fixed beta = 0.2, as in later TMCMC
    work (e.g. Betz et al. 2016), because the tempered targets shrink from stage to stage.
    """
    if not math.isfinite(acceptance_rate):
        return float(beta)
    b = beta * math.exp(settings.beta_gain * (acceptance_rate - settings.target_acceptance))
    return float(min(max(b, settings.beta_min), settings.beta_max))
