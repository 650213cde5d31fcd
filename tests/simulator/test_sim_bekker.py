"""Rolling sinkage of a smooth rigid wheel against Bekker's closed form (textbook check).

z0 = [3 W / ((3 - n) k b sqrt(2 R))]^(2 / (2n + 1)) with k = k_c / b + k_phi (Bekker 1956; Wong,
Theory of Ground Vehicles). The conditions of the derivation: slip 0, no elastic rebound (K huge),
no bulldozing, the Bekker pressure without border taper. Bekker replaces the integral of (1 - u^2)^n
by (3 - n)/3, exact only at n = 1; the tolerance of 15 % covers that and the dx = 5 mm grid.
"""

import numpy as np
import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_swt


def bekker_sinkage(W: float, n: float, k: float, b: float, R: float) -> float:
    return (3 * W / ((3 - n) * k * b * np.sqrt(2 * R))) ** (2 / (2 * n + 1))


@pytest.mark.parametrize(
    ("W", "n", "k_phi"),
    [(315.0, 1.1, 1e7), (150.0, 1.0, 5e6), (500.0, 1.3, 3e7), (315.0, 0.8, 2e6)],
)
def test_smooth_wheel_matches_bekker(W, n, k_phi):
    wheel = WheelGeometry(n_grousers=0)
    soil = SoilParams(n=n, k_phi=k_phi, k_c=0.0, K=1e10)
    rig = RigConfig(
        W=W,
        slip=0.0,
        border_taper=False,
        bulldozing=False,
        duration=25.0,
        offset_F=10.0,
        offset_T=10.0,
        offset_z=10.0,
    )
    result = simulate_swt(soil, wheel, rig)
    assert result.status == "ok"
    z0 = bekker_sinkage(W, n, k_phi, wheel.b, wheel.R)
    assert result.means.z == pytest.approx(z0, rel=0.15)


def test_bekker_with_cohesive_modulus_uses_b_eff():
    """With k_c != 0 the model uses k_c / b_eff (eq. 7, 11); Bekker's formula with b_eff agrees."""
    wheel = WheelGeometry(n_grousers=0)
    soil = SoilParams(n=1.0, k_phi=4e6, k_c=1.5e5, K=1e10)
    rig = RigConfig(
        slip=0.0,
        border_taper=False,
        bulldozing=False,
        duration=25.0,
        offset_F=10.0,
        offset_T=10.0,
        offset_z=10.0,
    )
    result = simulate_swt(soil, wheel, rig)
    b_eff = float(np.mean(result.series["b_eff"][result.series["t"] >= 10.0]))
    z0 = bekker_sinkage(rig.W, 1.0, soil.k_c / b_eff + soil.k_phi, wheel.b, wheel.R)
    assert result.means.z == pytest.approx(z0, rel=0.15)
