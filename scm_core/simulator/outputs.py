"""The simulator's output series: its columns (the time, the responses, the force budget), one
step's record into them, their steady means over the averaging windows (paper section 4.3) and
the early stop's test of a settled run."""

from __future__ import annotations

import numpy as np
from numba import njit

from .contact import R_BEFF, R_FX, R_FXCAP, R_FXN, R_FXS, R_FY, R_FZ, R_T
from .layout import P_OFF_F, P_OFF_T, P_OFF_Z, P_R, P_SETTLE, P_W

# columns of the output series
S_T = 0
S_F = 1
S_TORQUE = 2
S_Z = 3
S_FN = 4
S_BEFF = 5
S_FY = 6  # lateral force along the axle [N] (a steered wheel; 0 straight)
# the force budget: F = S_F_NORMAL + S_F_SHEAR + S_F_CAP + S_F_HEAP, Fy = its shear + S_FY_SIDE
S_F_NORMAL = 7  # normal stresses on the rim along the heading (compaction, bulldozing) [N]
S_F_SHEAR = 8  # shear stresses on the rim along the heading (thrust, drag) [N]
S_F_CAP = 9  # the Coulomb cap's cut of the forward thrust (<= 0) [N]
S_F_HEAP = 10  # the bow wave's own wedge pushing the rim back (<= 0) [N]
S_FY_SIDE = 11  # the leading side's passive force along the axle [N]
S_P_COMPACTION = 12  # the plastic work done on the soil's nodes per time [W]
N_SERIES = 13
#: the force budget's columns (swt.ForceBudget's fields, in order)
BUDGET_COLUMNS = (S_F_NORMAL, S_F_SHEAR, S_F_CAP, S_F_HEAP, S_FY_SIDE, S_P_COMPACTION)
#: the series columns of the steady means, in the order of the responses
#: (scm_core.signals.responses.RESPONSES: F, T, z, Fy)
MEAN_COLUMNS = (S_F, S_TORQUE, S_Z, S_FY)
N_MEANS = len(MEAN_COLUMNS)


@njit(cache=True, nogil=True)
def record_step(
    acc: np.ndarray, res: np.ndarray, z: float, heap_force: float, side: float, power: float
) -> None:
    """Add one step's forces ``res`` (contact.R_*), sinkage ``z`` [m], the bow wave's wedge
    force and the side's passive force [N] and the compaction's power [W] to the sample's sums
    ``acc`` (N_SERIES)."""
    acc[S_F] += res[R_FX]
    acc[S_TORQUE] += res[R_T]
    acc[S_Z] += z
    acc[S_FN] += res[R_FZ]
    acc[S_BEFF] += res[R_BEFF]
    acc[S_FY] += res[R_FY]
    acc[S_F_NORMAL] += res[R_FXN]
    acc[S_F_SHEAR] += res[R_FXS]
    acc[S_F_CAP] += res[R_FXCAP]
    acc[S_F_HEAP] -= heap_force
    acc[S_FY_SIDE] += side
    acc[S_P_COMPACTION] += power


@njit(cache=True, nogil=True)
def settled(series: np.ndarray, prm: np.ndarray, duration: float) -> bool:
    """Whether the steady means of F, T, z and Fy so far are settled for early stop: each mean over
    its window so far (offset to the last sample, length L), extrapolated linearly to the whole
    window (offset to ``duration``, length L_f), moves by at most the tolerance. For a mean
    drifting at rate a the two halves of the window so far differ by a L / 2 and the whole
    window's mean by a (L_f - L) / 2 from the one so far, so the test is
    |mean(second half) - mean(first half)| (L_f - L) / L <= tol, with tol = P_SETTLE times W
    (F and Fy, over F's window), W R (T) and R (z); a straight wheel's Fy, zero, is settled."""
    n = series.shape[0]
    if n < 8:
        return False
    t_now = series[n - 1, S_T]
    offs = (prm[P_OFF_F], prm[P_OFF_T], prm[P_OFF_Z], prm[P_OFF_F])
    cols = MEAN_COLUMNS
    scales = (prm[P_W], prm[P_W] * prm[P_R], prm[P_R], prm[P_W])
    for q in range(N_MEANS):
        i0 = 0
        while i0 < n and series[i0, S_T] < offs[q] - 1e-9:
            i0 += 1
        m = n - i0
        length = t_now - offs[q]
        if m < 4 or length <= 0.0:
            return False
        half = m // 2
        a = 0.0
        for i in range(i0, i0 + half):
            a += series[i, cols[q]]
        b = 0.0
        for i in range(i0 + half, n):
            b += series[i, cols[q]]
        change = abs(b / (m - half) - a / half) * (duration - offs[q] - length) / length
        if change > prm[P_SETTLE] * scales[q]:
            return False
    return True


@njit(cache=True, nogil=True)
def _window_mean(series: np.ndarray, col: int, offset: float) -> float:
    """Mean of the series column ``col`` over t >= ``offset`` [s]; NaN for an empty window."""
    s = 0.0
    n = 0
    for i in range(series.shape[0]):
        if series[i, S_T] >= offset - 1e-9:
            s += series[i, col]
            n += 1
    return s / n if n > 0 else np.nan


@njit(cache=True, nogil=True)
def steady_means(series: np.ndarray, prm: np.ndarray) -> np.ndarray:
    """Means (N_MEANS,) of F, T, z and Fy (the order of scm_core.signals.responses.RESPONSES)
    over t >= their offsets (paper section 4.3: 20 s, 20 s, 1 s; Fy over F's window); NaN
    for an empty window."""
    out = np.full(N_MEANS, np.nan)
    offs = (prm[P_OFF_F], prm[P_OFF_T], prm[P_OFF_Z], prm[P_OFF_F])
    for q in range(N_MEANS):
        out[q] = _window_mean(series, MEAN_COLUMNS[q], offs[q])
    return out


@njit(cache=True, nogil=True)
def budget_means(series: np.ndarray, prm: np.ndarray) -> np.ndarray:
    """Means of the force budget's columns (BUDGET_COLUMNS) over F's window, as F's own."""
    out = np.full(len(BUDGET_COLUMNS), np.nan)
    for q in range(len(BUDGET_COLUMNS)):
        out[q] = _window_mean(series, BUDGET_COLUMNS[q], prm[P_OFF_F])
    return out
