"""Pure numerics for SWT signals: zero-phase low-pass filter and steady means with errors.

Paper section 4.3: experimental signals are filtered and averaged after an offset (40 s) once
the run is steady; the steady means enter the likelihood, eq. (15).
"""

from dataclasses import dataclass

import numpy as np

from .responses import RESPONSE_KEYS

#: Default low-pass cutoff (Hz). Grouser passage on an SWT rig is of order 0.1-2 Hz; 1 Hz keeps
#: the slow response and removes sensor noise. With fewer than 5 Hz sampling the default becomes
#: 0.2 x sample rate (0.4 x Nyquist).
DEFAULT_CUTOFF_HZ = 1.0
DEFAULT_ORDER = 4
#: Sokal's window constant: sum the autocorrelation up to the first lag M >= C * tau(M).
SOKAL_C = 5.0
#: block length of the lag-product FFTs, and the first range of lags tried for Sokal's window
_BLOCK = 1 << 16
_FIRST_LAGS = 1024


@dataclass(frozen=True)
class ResponseStat:
    """Steady statistics of one response in SI units (N, Nm or m).

    ``mean``: steady mean; ``se``: standard error of the mean; ``sd``: standard deviation of the
    signal in the window (time series) or across trials (summary); ``n_eff``: effective number
    of independent samples behind ``se`` (n / tau for a time series, the trial count for a
    summary).
    """

    mean: float
    se: float
    sd: float
    n_eff: float


@dataclass(frozen=True)
class SteadyResponse:
    """Steady F (N), T (Nm), z (m) and Fy (N) over the window [t0, t1] (s) of ``n_samples``
    samples; a response the log does not carry is None."""

    F: ResponseStat | None
    T: ResponseStat | None
    z: ResponseStat | None
    window: tuple[float, float]
    n_samples: int
    rate_hz: float
    cutoff_hz: float
    Fy: ResponseStat | None = None

    def stats(self) -> dict[str, ResponseStat]:
        """``{"F": ..., "T": ..., "z": ..., "Fy": ...}`` of the responses present."""
        return {k: getattr(self, k) for k in RESPONSE_KEYS if getattr(self, k) is not None}


def sample_rate(t: np.ndarray) -> float:
    """Sample rate (Hz) from the median time step of ``t`` (s)."""
    return 1.0 / float(np.median(np.diff(np.asarray(t, dtype=np.float64))))


def default_cutoff(rate_hz: float) -> float:
    """Default cutoff (Hz): min(1 Hz, 0.2 x sample rate)."""
    return min(DEFAULT_CUTOFF_HZ, 0.2 * rate_hz)


def lowpass(
    x: np.ndarray, rate_hz: float, cutoff_hz: float | None = None, order: int = DEFAULT_ORDER
) -> np.ndarray:
    """Zero-phase Butterworth low-pass (SOS form, forward-backward with ``sosfiltfilt``).

    Running the ``order`` filter forwards and backwards gives zero phase lag and a magnitude of
    |H|^2: the effective order doubles and the gain at ``cutoff_hz`` is -6 dB (not -3 dB). The
    DC gain is 1, so means are preserved. ``cutoff_hz`` None: :func:`default_cutoff`.
    """
    x = np.asarray(x, dtype=np.float64)
    cutoff = default_cutoff(rate_hz) if cutoff_hz is None else float(cutoff_hz)
    nyquist = 0.5 * rate_hz
    if not 0.0 < cutoff < nyquist:
        raise ValueError(f"cutoff {cutoff:g} Hz must lie in (0, {nyquist:g}) Hz (Nyquist)")
    from scipy import signal  # on first use: scipy.signal takes a second to import

    sos = signal.butter(order, cutoff, btype="low", fs=rate_hz, output="sos")
    padlen = min(3 * (2 * len(sos) + 1), x.size - 1)
    return signal.sosfiltfilt(sos, x, padlen=padlen)


def lag_products(d: np.ndarray, max_lag: int) -> np.ndarray:
    """s_k = sum_i d_i d_(i+k) for k = 0..max_lag (< d.size), by FFT over blocks.

    Each block of B >= max_lag samples is correlated with itself and the max_lag samples that
    follow (zero padding to B + max_lag points: no circular wrap), so every pair (i, i + k) is
    counted once and the memory is O(B + max_lag) rather than O(2 d.size).
    """
    from scipy import fft as sp_fft

    n = d.size
    lag = min(int(max_lag), n - 1)
    block = max(lag, _BLOCK)
    nfft = sp_fft.next_fast_len(block + lag, real=True)
    out = np.zeros(lag + 1)
    for start in range(0, n, block):
        head = sp_fft.rfft(d[start : start + block], nfft)
        tail = sp_fft.rfft(d[start : start + block + lag], nfft)
        out += sp_fft.irfft(np.conj(head) * tail, nfft)[: lag + 1]
    return out


def autocorrelation(x: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Normalised autocorrelation rho_k, k = 0..max_lag (default n - 1; biased estimator)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    acov = lag_products(x - x.mean(), n - 1 if max_lag is None else max_lag)
    if acov[0] <= 0:
        return np.zeros(acov.size)
    return acov / acov[0]


def integrated_autocorr_time(x: np.ndarray, c: float = SOKAL_C) -> float:
    """Integrated autocorrelation time tau = 1 + 2 sum_k rho_k (in samples), at least 1.

    Sokal's automatic window: the sum runs to the first lag M with M >= c tau(M), which keeps
    the truncation bias ~exp(-c) for exponentially decaying correlations while bounding the
    estimator's variance, var(tau)/tau^2 ~ 2 (2M + 1) / n. tau is floored at 1 (never claim
    more precision than independent samples) and is 1 for a constant signal. The lags are
    computed in growing ranges (1024, x4, ... up to n - 1) until the window closes, so memory
    follows M, not n.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    lag = min(_FIRST_LAGS, n - 1)
    while True:
        rho = autocorrelation(x, lag)
        if rho[0] == 0:
            return 1.0
        taus = 2.0 * np.cumsum(rho) - 1.0
        stop = np.arange(taus.size) >= c * taus
        if stop.any() or lag >= n - 1:
            m = int(np.argmax(stop)) if stop.any() else taus.size - 1
            return max(float(taus[m]), 1.0)
        lag = min(4 * lag, n - 1)


def standard_error(x: np.ndarray) -> tuple[float, float]:
    """Standard error of the mean of a correlated stationary series, and n_eff = n / tau.

    se = sd sqrt(tau / n), the large-n variance of the mean sigma^2 tau / n (for AR(1) noise
    tau = (1 + rho) / (1 - rho)); the naive sd / sqrt(n) is too small by sqrt(tau).
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    tau = integrated_autocorr_time(x)
    sd = float(np.std(x, ddof=1)) if n > 1 else 0.0
    return sd * np.sqrt(tau / n), n / tau


def steady_stat(raw: np.ndarray, filtered: np.ndarray, mask: np.ndarray) -> ResponseStat:
    """Steady statistics of one signal over the window ``mask``.

    Mean of the filtered signal (as in the paper, Fig. 3); sd of the unfiltered signal; standard
    error from the integrated autocorrelation time of the unfiltered signal. Why unfiltered:
    the variance of a mean is governed by the spectral density at zero frequency, which a
    unit-DC-gain low-pass leaves unchanged, whereas the filter's own long smoothing correlation
    makes the tau estimate on the filtered signal noisier and more truncation-biased.
    Periodic components (grouser passage) with periods near the Sokal window make se
    conservative (too large), never too small.
    """
    window = np.asarray(raw, dtype=np.float64)[mask]
    se, n_eff = standard_error(window)
    sd = float(np.std(window, ddof=1)) if window.size > 1 else 0.0
    mean = float(np.mean(np.asarray(filtered, dtype=np.float64)[mask]))
    return ResponseStat(mean=mean, se=float(se), sd=sd, n_eff=float(n_eff))


def steady_response(
    t: np.ndarray,
    F: np.ndarray | None,
    T: np.ndarray | None,
    z: np.ndarray | None,
    offset: float = 40.0,
    cutoff_hz: float | None = None,
    order: int = DEFAULT_ORDER,
    Fy: np.ndarray | None = None,
) -> SteadyResponse:
    """Filter F (N), T (Nm), z (m) and Fy (N) and average them over t >= t[0] + offset (s); a
    response passed as None (not measured) stays None.

    Assumes a checked, regularly sampled time axis ``t`` (s); see ``validation``.
    """
    t = np.asarray(t, dtype=np.float64)
    rate = sample_rate(t)
    cutoff = default_cutoff(rate) if cutoff_hz is None else float(cutoff_hz)
    mask = t >= t[0] + offset
    if not mask.any():
        raise ValueError(f"no samples after the offset {offset:g} s")
    stats = {
        key: None if x is None else steady_stat(x, lowpass(x, rate, cutoff, order), mask)
        for key, x in zip(RESPONSE_KEYS, (F, T, z, Fy), strict=True)
    }
    t_win = t[mask]
    return SteadyResponse(
        **stats,
        window=(float(t_win[0]), float(t_win[-1])),
        n_samples=int(mask.sum()),
        rate_hz=rate,
        cutoff_hz=cutoff,
    )
