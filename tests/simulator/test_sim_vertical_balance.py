"""Newton's second law on average: over a window the soil carries the wheel's weight.

The wheel's vertical momentum changes over a window of length T by m (v_end - v_start); the
sinkage rate is a few mm/s at most, so for a 2.6 kg wheel over 1.5 s the mean inertial force is
below 1e-2 N, under 0.1 % of W. The mean normal force over the window therefore equals W to well
within 1 %, at any time step: a solve that stops short of the force balance (a height tolerance
coarser than the inertia term m dz / dt^2 allows) breaks it at short steps.
"""

from __future__ import annotations

import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_swt

SAND = SoilParams(k_c=0.0, k_phi=8e6, n=1.0, phi=29.0, c=0.0, J=0.01, K=7e6, repose_angle=29.0)
CMU_GROUSERS = WheelGeometry(R=0.058, b=0.05, n_grousers=12, grouser_height=0.005)
CMU_OPTIONS = dict(shear="displacement", drive_digging="mobilised", skid_ploughing="sliding_face")

CASES = {
    # the paper's wheel at a twentieth of its time step
    "paper, dt 1 ms": (SoilParams(), WheelGeometry(), RigConfig(dt=0.001, duration=6.0)),
    # a CMU-like grousered wheel at slip 0.9 on half the default grid: dt 0.29 ms, where the
    # axle height's 1 um tolerance alone was 31 N of a 25.7 N wheel (mean Fn was 0.33 W)
    "CMU 12 x 5 mm grousers, slip 0.9, dt 0.29 ms": (
        SAND,
        CMU_GROUSERS,
        RigConfig(
            W=25.7,
            slip=0.9,
            carriage_speed=0.01,
            dx=0.00116,
            dt=0.000291,
            duration=3.0,
            **CMU_OPTIONS,
        ),
    ),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_mean_normal_force_is_the_weight(name: str) -> None:
    soil, wheel, rig = CASES[name]
    r = simulate_swt(soil, wheel, rig)
    assert r.status == "ok"
    t = r.series["t"]
    window = t >= 0.5 * t[-1]
    mean_fn = float(r.series["normal_force"][window].mean())
    assert mean_fn == pytest.approx(r.rig.W, rel=0.01)
