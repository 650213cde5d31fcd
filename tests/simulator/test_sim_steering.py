"""A steered wheel (RigConfig.slip_angle, issue 70): the wheel slides along its axle at
v sin(beta) while its plane sees v cos(beta); the shear follows the slip velocity's direction
(Janosi-Hanamoto along the slip, Ishigami et al. 2007) and the leading side pushes the soil
beside the rut with Rankine's passive pressure. Checks from mechanics, not from the code:
straight driving untouched, mirror symmetry in beta, Coulomb's wedge for the side's passive
force, and the base friction of a wheel dragged along its axle."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_swt
from scm_core.simulator.layout import P_V, P_VLAT, pack
from scm_core.simulator.side import passive_force_per_length

#: short runs of the paper's wheel (coarse numerics: the checks are relations, not values)
FAST = {"duration": 12.0, "dt": 0.04, "dx": 0.01, "offset_F": 6.0, "offset_T": 6.0, "offset_z": 6.0}


def test_straight_is_packed_as_before() -> None:
    """beta = 0: the heading's speed is the carriage's, bit for bit, and nothing slides along
    the axle (the kernel then takes its straight path: the physics drift set is unchanged)."""
    rig = RigConfig(carriage_speed=0.01, slip=0.2)
    prm = pack(SoilParams(), WheelGeometry(), rig)
    assert prm[P_V] == 0.01 and prm[P_VLAT] == 0.0 and not math.copysign(1.0, prm[P_VLAT]) < 0
    r = simulate_swt(rig=rig.model_copy(update=FAST))
    assert r.ok and np.all(r.series["Fy"] == 0.0) and r.means.Fy == 0.0


@pytest.mark.parametrize("beta", [30.0, 60.0])
def test_mirror_angles_give_the_same_forces_and_opposite_lateral_force(beta: float) -> None:
    """+beta and -beta are mirror images across the wheel's plane: F, T, z the same, Fy
    opposite (to the rounding of the row a sliding wheel sits on, ~1e-8 relative)."""
    soil = SoilParams(bulk_density=1330.0)
    plus = simulate_swt(soil, rig=RigConfig(slip_angle=beta, **FAST))
    minus = simulate_swt(soil, rig=RigConfig(slip_angle=-beta, **FAST))
    assert plus.ok and minus.ok
    for name in ("F", "T", "z"):
        a, b = getattr(plus.means, name), getattr(minus.means, name)
        assert a == pytest.approx(b, rel=1e-6, abs=1e-9), name
    assert plus.means.Fy > 0.0  # against the slide toward -y
    assert minus.means.Fy == pytest.approx(-plus.means.Fy, rel=1e-6)


def _coulomb_passive(gamma: float, c: float, phi_deg: float, h: float) -> float:
    """Coulomb's passive force [N/m] on a smooth vertical wall of depth h: the least, over the
    failure plane's angle a from the horizontal, of the force that pushes the wedge up the
    plane (weight W = gamma h^2 / (2 tan a), friction phi and cohesion c h / sin a on it)."""
    phi = math.radians(phi_deg)

    def force(a: float) -> float:
        weight = 0.5 * gamma * h * h / math.tan(a)
        # equilibrium of the wedge: wall force P horizontal, plane reaction R at phi below its
        # normal, cohesion along the plane against the wedge's upward slide
        cohesion = c * h / math.sin(a)
        return weight * math.tan(a + phi) + cohesion * math.cos(phi) / math.cos(a + phi)

    best = minimize_scalar(force, bounds=(1e-3, math.pi / 2 - phi - 1e-3), method="bounded",
                           options={"xatol": 1e-10})  # fmt: skip
    return float(best.fun)


@pytest.mark.parametrize(
    ("gamma", "c", "phi", "h"),
    [
        (13047.0, 0.0, 30.0, 0.05),
        (13047.0, 0.0, 37.0, 0.07),
        (15000.0, 800.0, 25.0, 0.03),
        (0.0, 1200.0, 30.0, 0.04),
    ],
)
def test_side_passive_force_is_coulombs_wedge(gamma, c, phi, h) -> None:
    """Rankine's passive force of a smooth vertical wall equals Coulomb's least wedge force
    (here found numerically, independently of the closed form) to 1e-6; phi = 30 deg gives
    K_p = 3: 1.5 gamma h^2 without cohesion."""
    tan_phi = math.tan(math.radians(phi))
    got = passive_force_per_length(gamma, c, tan_phi, h)
    assert got == pytest.approx(_coulomb_passive(gamma, c, phi, h), rel=1e-6)
    if phi == 30.0 and c == 0.0:
        assert got == pytest.approx(1.5 * gamma * h * h, rel=1e-12)
    assert passive_force_per_length(gamma, c, tan_phi, -0.01) == 0.0


def test_a_locked_wheel_dragged_along_its_axle_slides_on_its_base() -> None:
    """90 deg, locked, weightless cohesionless soil (no side pressure): the wheel slides
    sideways over its footprint like a plate, so the lateral force is the base friction
    mu Sum(sigma dA) with the shear fully mobilised (J small): between W tan(phi) (a flat
    footprint) and W tan(phi) / cos(theta_1) (its edges inclined by the entry angle theta_1),
    and nothing along the heading (a symmetric footprint, no rotation)."""
    soil = SoilParams(J=1e-6, phi=30.0, c=0.0, bulk_density=0.0, bearing_inclination=0.0)
    rig = RigConfig(slip=-1.0, slip_convention="symmetric", slip_angle=90.0, **FAST)
    r = simulate_swt(soil, rig=rig)
    assert r.ok, r.status
    W, tan_phi = rig.W, math.tan(math.radians(30.0))
    R = WheelGeometry().R
    theta1 = math.acos(1.0 - r.means.z / R) if r.means.z < R else math.pi / 2
    assert W * tan_phi * 0.98 <= r.means.Fy <= W * tan_phi / math.cos(theta1) * 1.02, (
        r.means.Fy, W * tan_phi, math.degrees(theta1))  # fmt: skip
    assert abs(r.means.F) < 0.02 * W
