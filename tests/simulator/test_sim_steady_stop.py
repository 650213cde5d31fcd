"""Early stop of a settled run (``RigConfig.steady_tolerance``, issue 42).

The rule, checked at a quarter, a half and three quarters of the averaging window: the mean so
far over a window of length L, extrapolated linearly to the whole window L_f, moves by
|mean(second half) - mean(first half)| (L_f - L) / L. For a series drifting linearly at rate a
that is exactly the difference of the two means, a (L_f - L) / 2, which the first tests compute
in closed form.
"""

from __future__ import annotations

import numpy as np
import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_swt
from scm_core.simulator.layout import N_PARAMS, P_OFF_F, P_OFF_T, P_OFF_Z, P_R, P_SETTLE, P_W
from scm_core.simulator.outputs import S_F, S_FY, S_T, S_TORQUE, S_Z, settled

DURATION = 10.0  # s
OFFSET = 4.0  # s, all three responses
W, R = 100.0, 0.1  # N, m


def _prm(tol: float) -> np.ndarray:
    p = np.zeros(N_PARAMS)
    p[P_OFF_F] = p[P_OFF_T] = p[P_OFF_Z] = OFFSET
    p[P_W], p[P_R], p[P_SETTLE] = W, R, tol
    return p


def _series(t_end: float, drift_F: float) -> np.ndarray:
    """Samples at 100 Hz up to t_end: F = -10 + drift_F t [N], T = 5 N m, z = 0.02 m."""
    t = np.arange(1, int(round(t_end * 100)) + 1) / 100.0
    s = np.zeros((t.size, S_FY + 1))
    s[:, S_T] = t
    s[:, S_F] = -10.0 + drift_F * t
    s[:, S_TORQUE] = 5.0
    s[:, S_Z] = 0.02
    return s


def test_a_constant_series_is_settled_at_the_first_check() -> None:
    assert settled(_series(OFFSET + 0.25 * (DURATION - OFFSET), 0.0), _prm(1e-6), DURATION)


@pytest.mark.parametrize("fraction", [0.25, 0.5, 0.75])
def test_a_drift_is_extrapolated_to_the_whole_window(fraction: float) -> None:
    """F drifts at a = 0.1 N/s: the mean over [offset, t] differs from the whole window's by
    a (L_f - L) / 2 (closed form); the test passes just above that change, fails just below."""
    a = 0.1
    t_now = OFFSET + fraction * (DURATION - OFFSET)
    s = _series(t_now, a)
    mean_so_far = s[s[:, S_T] >= OFFSET - 1e-9, S_F].mean()
    whole = _series(DURATION, a)
    mean_whole = whole[whole[:, S_T] >= OFFSET - 1e-9, S_F].mean()
    change = abs(mean_whole - mean_so_far)
    assert change == pytest.approx(a * (DURATION - t_now) / 2, rel=0.02)
    assert settled(s, _prm(1.02 * change / W), DURATION)
    assert not settled(s, _prm(0.98 * change / W), DURATION)


def test_a_drifting_lateral_force_is_not_settled() -> None:
    """A steered wheel's Fy counts as F does (tolerance tol W over F's window): F, T and z
    constant and Fy drifting at 0.1 N/s move the whole window's Fy mean by 0.1 (6 - 1.5) / 2 =
    0.225 N at the first check, over tol 0.002 (0.2 N of W 100 N) and under tol 0.003."""
    s = _series(OFFSET + 0.25 * (DURATION - OFFSET), 0.0)
    s[:, S_FY] = 3.0 + 0.1 * s[:, S_T]
    assert not settled(s, _prm(0.002), DURATION)
    assert settled(s, _prm(0.003), DURATION)


def test_sinkage_tolerance_scales_with_the_radius() -> None:
    """z's tolerance is tol R: at the first check (L = 1.5 s of L_f = 6 s) a sinkage drift of
    1 mm/s moves the mean by 1 mm/s (6 - 1.5) s / 2 = 2.25 mm, over tol 0.01 (1 mm of R 0.1 m)
    and under tol 0.04 (4 mm)."""
    s = _series(OFFSET + 0.25 * (DURATION - OFFSET), 0.0)
    s[:, S_Z] = 0.02 + 0.001 * s[:, S_T]
    assert not settled(s, _prm(0.01), DURATION)
    assert settled(s, _prm(0.04), DURATION)


SOIL = SoilParams(k_c=0.0, k_phi=8e6, n=1.0, phi=29.0, c=0.0, J=0.01, K=7e6, repose_angle=29.0)
CMU_SMOOTH = WheelGeometry(R=0.058, b=0.05)


def test_a_settled_run_stops_early_within_its_tolerance() -> None:
    """The CMU smooth wheel at zero slip settles at once: with a tolerance of 1 % it stops at a
    check before the end, its means within 1 % of W (F) and of R (z) of the whole window's."""
    rig = RigConfig(
        W=25.7,
        slip=0.0,
        carriage_speed=0.01,
        shear="displacement",
        drive_digging="mobilised",
        offset_z_fraction=0.4,
    )
    full = simulate_swt(SOIL, CMU_SMOOTH, rig)
    early = simulate_swt(SOIL, CMU_SMOOTH, rig.model_copy(update={"steady_tolerance": 0.01}))
    assert full.ok and early.ok
    assert early.diagnostics["steps"] <= 0.85 * full.diagnostics["steps"] + 1
    assert early.series["t"][-1] < full.series["t"][-1]
    assert abs(early.means.F - full.means.F) <= 0.01 * rig.W
    assert abs(early.means.z - full.means.z) <= 0.01 * CMU_SMOOTH.R
    # same settings, same bits
    again = simulate_swt(SOIL, CMU_SMOOTH, rig.model_copy(update={"steady_tolerance": 0.01}))
    assert again.means == early.means


def test_no_tolerance_runs_the_whole_window() -> None:
    r = simulate_swt(rig=RigConfig(duration=5.0, offset_F=2.0, offset_T=2.0, offset_z=0.1))
    assert r.diagnostics["steps"] == round(5.0 / r.rig.dt)


def test_the_tolerance_is_a_fraction() -> None:
    with pytest.raises(ValueError, match="steady_tolerance"):
        RigConfig(steady_tolerance=1.5)
