"""Zero-phase filtering, steady means and autocorrelation-aware standard errors."""

import numpy as np
import pytest
from scipy import signal

from scm_core.signals import (
    integrated_autocorr_time,
    lowpass,
    standard_error,
    steady_response,
)
from scm_core.signals.processing import default_cutoff

FS = 100.0


def phase(t: np.ndarray, x: np.ndarray, f: float) -> float:
    """Phase (rad) of the f-Hz component of x by least squares on sin and cos."""
    basis = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)])
    a, b, _ = np.linalg.lstsq(basis, x, rcond=None)[0]
    return float(np.arctan2(b, a))


def test_lowpass_sine_has_no_lag():
    t = np.arange(0, 60, 1 / FS)
    f = 0.2
    x = np.sin(2 * np.pi * f * t)
    inner = slice(1000, -1000)  # away from the padded ends
    y = lowpass(x, FS, cutoff_hz=1.0)
    assert abs(phase(t[inner], y[inner], f) - phase(t[inner], x[inner], f)) < 1e-3
    np.testing.assert_allclose(y[inner], x[inner], atol=1e-3)  # gain 1 well below cutoff
    # the test can see lag: the same filter run causally lags by ~0.3 rad
    sos = signal.butter(4, 1.0, fs=FS, output="sos")
    causal = signal.sosfilt(sos, x)
    assert phase(t[inner], causal[inner], f) - phase(t[inner], x[inner], f) < -0.2


def test_lowpass_step_is_symmetric_about_the_edge():
    t = np.arange(0, 60, 1 / FS)
    x = (t >= 30.0).astype(float)
    y = lowpass(x, FS, cutoff_hz=1.0)
    edge = int(np.argmax(x))  # first sample at 1; symmetry point half a sample before
    k = np.arange(0, 300)
    np.testing.assert_allclose(y[edge + k] + y[edge - 1 - k], 1.0, atol=1e-6)
    assert 0.4 < y[edge] < 0.6
    assert abs(y[100] - 0.0) < 1e-6 and abs(y[-100] - 1.0) < 1e-6


def test_lowpass_removes_noise_above_cutoff():
    rng = np.random.default_rng(1)
    x = rng.normal(size=20000)
    y = lowpass(x, FS, cutoff_hz=1.0)
    # white noise power passing a |H|^2 (order 8 effective) filter with 1 Hz of 50 Hz band
    assert np.std(y) < 0.2 * np.std(x)


def test_lowpass_checks_cutoff_and_defaults():
    with pytest.raises(ValueError, match="Nyquist"):
        lowpass(np.zeros(100), 10.0, cutoff_hz=5.0)
    with pytest.raises(ValueError):
        lowpass(np.zeros(100), 10.0, cutoff_hz=0.0)
    assert default_cutoff(100.0) == 1.0
    assert default_cutoff(2.0) == pytest.approx(0.4)
    y = lowpass(np.ones(30), 2.0)  # short series, default cutoff below Nyquist
    np.testing.assert_allclose(y, 1.0)


def test_steady_mean_of_constant_sine_and_noise():
    rng = np.random.default_rng(2)
    t = np.arange(0, 180, 1 / FS)
    c, amp, f, sigma = 20.0, 2.0, 0.3, 1.0
    x = c + amp * np.sin(2 * np.pi * f * t + 0.7) + rng.normal(0, sigma, t.size)
    res = steady_response(t, x, x / 4, x / 1000, offset=40.0)
    assert res.window[0] == pytest.approx(40.0)
    assert res.window[1] == pytest.approx(t[-1])
    n = res.n_samples
    assert n == int(np.sum(t >= 40.0))
    # noise: 4 standard errors; sine: its mean over a window of length Tw is at most A/(pi f Tw)
    tol = 4 * sigma / np.sqrt(n) + amp / (np.pi * f * (res.window[1] - res.window[0]))
    assert abs(res.F.mean - c) < tol
    assert abs(res.T.mean - c / 4) < tol / 4
    assert abs(res.z.mean - c / 1000) < tol / 1000
    # sd is that of the unfiltered signal: sqrt(sigma^2 + A^2/2)
    assert res.F.sd == pytest.approx(np.sqrt(sigma**2 + amp**2 / 2), rel=0.03)
    # the periodic part makes se conservative, never below the white-noise value
    assert res.F.se >= 0.9 * sigma / np.sqrt(n)
    assert res.cutoff_hz == 1.0 and res.rate_hz == pytest.approx(FS)


def ar1(n: int, rho: float, seed: int) -> np.ndarray:
    """Stationary AR(1) with unit marginal variance."""
    rng = np.random.default_rng(seed)
    e = rng.normal(0, np.sqrt(1 - rho**2), n)
    e[0] = rng.normal()  # start in the stationary distribution
    return signal.lfilter([1.0], [1.0, -rho], e)


@pytest.mark.parametrize("seed", range(5))
def test_standard_error_of_ar1_matches_exact_formula(seed):
    """se^2 -> sigma^2 / n * (1 + rho) / (1 - rho) for AR(1) noise.

    Tolerance 25 %: Sokal's estimator has var(tau)/tau^2 ~ 2 (2M + 1) / n with M ~ 5 tau = 95,
    i.e. about 9 % on tau and 4.5 % on se for n = 50000, and its truncation bias is ~exp(-5);
    25 % is over five standard deviations. The naive sd/sqrt(n) is off by sqrt(19) ~ 4.4.
    """
    n, rho = 50_000, 0.9
    x = ar1(n, rho, seed)
    exact = np.sqrt(1.0 / n * (1 + rho) / (1 - rho))
    se, n_eff = standard_error(x)
    assert se == pytest.approx(exact, rel=0.25)
    assert n_eff == pytest.approx(n * (1 - rho) / (1 + rho), rel=0.5)
    naive = np.std(x, ddof=1) / np.sqrt(n)
    assert naive < 0.3 * exact


def test_steady_response_se_uses_unfiltered_autocorrelation():
    n, rho = 50_000, 0.9
    t = np.arange(n) / FS
    x = 3.0 + ar1(n, rho, 7)
    res = steady_response(t, x, x, x, offset=0.0)
    exact = np.sqrt(1.0 / n * (1 + rho) / (1 - rho))
    assert res.F.se == pytest.approx(exact, rel=0.25)
    assert res.F.n_eff == pytest.approx(n / 19, rel=0.5)


def test_autocorrelation_time_edge_cases():
    assert integrated_autocorr_time(np.full(100, 3.0)) == 1.0
    rng = np.random.default_rng(3)
    assert integrated_autocorr_time(rng.normal(size=20000)) == pytest.approx(1.0, abs=0.1)
    # anti-correlated noise is floored at tau = 1 (conservative)
    assert integrated_autocorr_time(ar1(20000, -0.5, 4)) == 1.0
    se, n_eff = standard_error(np.full(50, 2.0))
    assert se == 0.0 and n_eff == 50


@pytest.mark.parametrize(("n", "max_lag"), [(10, 9), (1000, 50), (70_000, 3), (140_001, 2000)])
def test_blocked_lag_products_equal_the_direct_sums(n, max_lag):
    """sum_i d_i d_(i+k) over blocks (pairs straddling block edges included) equals the
    direct sum, to rounding (relative 1e-9 of s_0)."""
    from scm_core.signals.processing import lag_products

    d = np.random.default_rng(n).normal(size=n)
    direct = np.array([d[: n - k] @ d[k:] for k in range(max_lag + 1)])
    np.testing.assert_allclose(lag_products(d, max_lag), direct, rtol=0, atol=1e-9 * direct[0])


@pytest.mark.parametrize("phi", [0.0, 0.9, 0.999])
def test_windowed_tau_equals_the_full_fft_estimate(phi):
    """Growing lag ranges give Sokal's tau of the full-length FFT autocorrelation (numpy's
    FFT, zero-padded to a power of two), also when the window reaches far (phi 0.999: tau of
    about 2000 samples)."""
    x = ar1(200_000, phi, 9)
    n = x.size
    d = x - x.mean()
    f = np.fft.rfft(d, 1 << (2 * n - 1).bit_length())
    acov = np.fft.irfft(f * np.conj(f))[:n]
    taus = 2.0 * np.cumsum(acov / acov[0]) - 1.0
    stop = np.arange(n) >= 5.0 * taus
    expected = max(taus[int(np.argmax(stop))], 1.0)
    assert integrated_autocorr_time(x) == pytest.approx(expected, rel=1e-9)
    assert integrated_autocorr_time(x) == pytest.approx((1 + phi) / (1 - phi), rel=0.35)
