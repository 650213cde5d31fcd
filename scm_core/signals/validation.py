"""Checks on a parsed time series: time axis, sample rate and the averaging window."""

import numpy as np

from .errors import LogFormatError

MIN_RATE_HZ = 1.0
MAX_RATE_HZ = 1e5
#: largest accepted |dt - median dt| / median dt (a dropped sample gives 1.0)
MAX_JITTER = 0.5
MIN_WINDOW_SAMPLES = 20


def check_time_axis(
    t: np.ndarray,
    lines: np.ndarray | None = None,
    min_rate_hz: float = MIN_RATE_HZ,
    max_rate_hz: float = MAX_RATE_HZ,
    max_jitter: float = MAX_JITTER,
) -> float:
    """Check that time ``t`` (s) increases strictly at a sane, regular rate; return the rate (Hz).

    ``lines`` are the file line numbers of the samples, used in messages.
    """
    t = np.asarray(t, dtype=np.float64)
    lines = np.arange(1, t.size + 1) if lines is None else np.asarray(lines)
    if t.size < 2:
        raise LogFormatError(f"only {t.size} sample(s); need a time series")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        k = int(bad[0])
        raise LogFormatError(
            f"line {lines[k + 1]}: time not strictly increasing "
            f"({t[k + 1]:g} s after {t[k]:g} s on line {lines[k]})"
        )
    step = float(np.median(dt))
    rate = 1.0 / step
    if not min_rate_hz <= rate <= max_rate_hz:
        raise LogFormatError(
            f"sample rate {rate:.6g} Hz outside [{min_rate_hz:g}, {max_rate_hz:g}] Hz "
            "(check the time unit)"
        )
    deviation = np.abs(dt - step) / step
    k = int(np.argmax(deviation))
    if deviation[k] > max_jitter:
        raise LogFormatError(
            f"irregular sampling: step {dt[k]:.6g} s between lines {lines[k]} and {lines[k + 1]}"
            f" deviates {100 * deviation[k]:.0f}% from the median step {step:.6g} s "
            f"(tolerance {100 * max_jitter:.0f}%)"
        )
    return rate


def window_mask(t: np.ndarray, offset: float, min_samples: int = MIN_WINDOW_SAMPLES) -> np.ndarray:
    """Boolean mask of the averaging window t >= t[0] + offset (s); refuse short runs.

    The offset counts from the first sample (paper section 4.3: 40 s for experimental logs).
    """
    t = np.asarray(t, dtype=np.float64)
    if not np.isfinite(offset) or offset < 0:
        raise ValueError(f"offset must be finite and >= 0 s, got {offset!r}")
    duration = float(t[-1] - t[0])
    if duration <= offset:
        raise LogFormatError(
            f"run lasts {duration:.6g} s, not longer than the averaging offset {offset:g} s"
        )
    mask = t >= t[0] + offset
    n = int(mask.sum())
    if n < min_samples:
        raise LogFormatError(
            f"averaging window [{t[0] + offset:.6g}, {t[-1]:.6g}] s holds {n} sample(s); "
            f"need at least {min_samples}"
        )
    return mask
