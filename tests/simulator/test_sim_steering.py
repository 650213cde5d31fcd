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
from scm_core.simulator.side import passive_force_3d

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


@pytest.mark.parametrize("beta", [30.0, 60.0, 90.0])
def test_mirror_angles_give_the_same_forces_and_opposite_lateral_force(beta: float) -> None:
    """+beta and -beta are mirror images across the wheel's plane: F, T, z the same, Fy
    opposite. Not bit for bit: the kernel visits the rows in ascending y, so the two images
    sum in different orders (1e-16 relative), which a discrete event can amplify (a node at
    the footprint's leading edge loaded in one image and not the other: 1e-3 of F at 60 deg
    with this soil, 1e-8 elsewhere); 2e-3 is far inside the discretisation's own error (F
    moves 5 % under dx / 2, docs/simulator.md)."""
    soil = SoilParams(bulk_density=1330.0)
    plus = simulate_swt(soil, rig=RigConfig(slip_angle=beta, **FAST))
    minus = simulate_swt(soil, rig=RigConfig(slip_angle=-beta, **FAST))
    assert plus.ok and minus.ok
    for name in ("F", "T", "z"):
        a, b = getattr(plus.means, name), getattr(minus.means, name)
        assert a == pytest.approx(b, rel=2e-3, abs=1e-9), name
    assert plus.means.Fy > 0.0  # against the slide toward -y
    assert minus.means.Fy == pytest.approx(-plus.means.Fy, rel=2e-3)


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
def test_a_long_side_gets_coulombs_wedge(gamma, c, phi, h) -> None:
    """A long wall (length 1e6 times its depth: the side crescents' share r / w ~ 1e-6) gets
    Coulomb's least wedge force per length (found numerically here, independently of the
    closed form) to 1e-5: Rankine's 1/2 gamma h^2 K_p + 2 c h sqrt(K_p); phi = 30 deg gives
    K_p = 3: 1.5 gamma h^2 without cohesion."""
    tan_phi = math.tan(math.radians(phi))
    w = 1e6 * h
    got = passive_force_3d(gamma, c, tan_phi, h, w) / w
    assert got == pytest.approx(_coulomb_passive(gamma, c, phi, h), rel=1e-5)
    if phi == 30.0 and c == 0.0:
        assert got == pytest.approx(1.5 * gamma * h * h, rel=1e-5)
    assert passive_force_3d(gamma, c, tan_phi, -0.01, 0.1) == 0.0


def _mckyes_scan(gamma: float, c: float, phi_deg: float, d: float, w: float) -> float:
    """McKyes & Ali's wedge and crescents for a smooth vertical wall, minimised by a dense scan
    of the failure plane's angle (written out here from McKyes 1985, ch. 4, not from side.py)."""
    phi = math.radians(phi_deg)
    betas = np.linspace(1e-4, math.pi / 2 - phi - 1e-4, 200_001)
    r = d / np.tan(betas)
    den = 1.0 / np.tan(betas + phi)  # cos(alpha + delta) + sin(alpha + delta) cot(beta + phi)
    n_g = r / (2 * d) * (1 + 2 / 3 * r / w) / den
    n_c = (1 + 1 / np.tan(betas) / np.tan(betas + phi)) * (1 + r / w) / den
    return float(np.min(w * (gamma * d * d * n_g + c * d * n_c)))


@pytest.mark.parametrize(("d", "w"), [(0.05, 0.09), (0.08, 0.11), (0.03, 0.3), (0.06, 0.06)])
@pytest.mark.parametrize(("c", "phi"), [(0.0, 33.9), (600.0, 28.0)])
def test_a_short_side_fails_in_three_dimensions(d, w, c, phi) -> None:
    """The wheel's side is about as long as it is deep, and its failure spreads beyond its ends
    (McKyes & Ali 1977): the golden-section search finds the scanned minimum to 1e-7, the force
    exceeds the long wall's Rankine force over the same length, by more the shorter the wall
    (up to about twice for a square wall in this sand)."""
    gamma = 13047.0
    tan_phi = math.tan(math.radians(phi))
    got = passive_force_3d(gamma, c, tan_phi, d, w)
    assert got == pytest.approx(_mckyes_scan(gamma, c, phi, d, w), rel=1e-7)
    kp = math.tan(math.radians(45 + phi / 2)) ** 2
    rankine = (0.5 * gamma * d * d * kp + 2 * c * d * math.sqrt(kp)) * w
    assert 1.0 < got / rankine < 2.5
    assert passive_force_3d(gamma, c, tan_phi, d, 2 * w) / (2 * w) < got / w


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


@pytest.mark.parametrize("beta", [30.0, 60.0, 90.0])
@pytest.mark.parametrize("omega", [0.0, 0.08], ids=["locked", "driven"])
def test_a_steered_wheel_conserves_volume(beta: float, omega: float) -> None:
    """The flows of a steered wheel (the displaced soil's parallel share along the slip, the
    layer its rim drags along the axle into the soil beside the rut) move soil: only the
    documented compaction, and soil that would leave the grid (spilled), removes volume."""
    soil = SoilParams(shear_band=0.02, bulk_density=1330.0)
    rig = RigConfig(omega=omega, carriage_speed=0.01, slip_angle=beta, **FAST)
    d = simulate_swt(soil, rig=rig).diagnostics
    assert d["compacted_volume"] > 0.0
    balance = d["volume_final"] - d["volume_initial"] + d["compacted_volume"] + d["volume_spilled"]
    assert abs(balance) / d["compacted_volume"] < 1e-9
    assert d["volume_spilled"] <= 1e-3 * d["compacted_volume"]


def _rut_below_start(shear_band: float, shear: str) -> tuple[float, float]:
    """(depth [m] of the ground left behind a locked wheel dragged along its axle, under its
    centre, below the undisturbed level; its steady sinkage [m]) on a stiff soil (little
    pressing), the shear mobilised at once (J small) and the layer dragged at the slip."""
    soil = SoilParams(k_phi=5e8, k_c=0.0, n=1.0, c=0.0, phi=30.0, J=1e-4, K=1e9,
                      shear_band=shear_band, slip_flow=1.0)  # fmt: skip
    wheel = WheelGeometry(R=0.058, b=0.05, n_grousers=0)
    rig = RigConfig(W=20.0, omega=0.0, carriage_speed=0.01, slip_angle=90.0, duration=20.0,
                    dt=0.02, dx=0.0025, offset_F=10.0, offset_T=10.0, offset_z=10.0,
                    shear=shear)  # fmt: skip
    r = simulate_swt(soil, wheel, rig)
    assert r.ok, r.status
    t = r.terrain
    centre = t.h[int(np.argmin(np.abs(t.x)))]
    # the wheel slides toward -y (beta > 0): the rows it left are the middle of those it
    # crossed, away from both the start (its first footprint) and the end (under it)
    crossed = np.flatnonzero(centre < -1e-6)
    behind = centre[crossed[len(crossed) // 3 : 2 * len(crossed) // 3]]
    return -float(np.median(behind)), r.means.z


@pytest.mark.parametrize("shear", ["velocity", "displacement"])
def test_a_wheel_dragged_sideways_digs_its_shear_band(shear: str) -> None:
    """Slip sinkage along the axle (issue 70; lateral_flow): a locked wheel dragged sideways
    slides its rim over the ground at the carriage speed, all of the ground enters across its
    side, and its slip along the travel is the carriage speed (as a locked straight wheel's),
    so every node it passes loses the whole layer the rim drags, shear_band d (slip_flow 1, the
    shear mobilised at once: J small), besides the pressing's own sinkage (0.07 mm on this
    stiff soil). The wheel then carries its load on the freshly dug ground at its leading side,
    which it presses a little more (0.6 mm here, about the load over the leading rows divided
    by k_phi, plus the elastic range): the rut is d to 1.2 d deep. Not less: the layer's share
    of the slip along the axle once read the rows' vertical motion as slip along the heading and
    dug 0.58 d. Not more: the layer is all the rim drags, dug once (the heading's share of a
    skid and the layer carried across the travel are zero here). A wheel with no layer digs
    none."""
    none, z0 = _rut_below_start(0.0, shear)
    assert none < 2e-4 and z0 < 5e-4
    dug, z = _rut_below_start(0.005, shear)
    assert 0.9 * 0.005 <= dug - none <= 1.2 * 0.005
    assert z > z0 + 0.002  # the wheel sinks into what it digs


@pytest.mark.parametrize("beta", [0.0, 45.0, -60.0])
def test_batch_lateral_force_is_the_single_runs_bit_for_bit(beta: float) -> None:
    """The batch simulator's steady means (simulate_batch: outputs.steady_means on a thread)
    carry the lateral force as the fourth mean, over F's window, and are the single run's
    SteadyMeans bit for bit (one computation for both paths); the columns are the responses'
    (scm_core.signals.responses), in order."""
    from dataclasses import fields

    from scm_core.signals.responses import RESPONSE_KEYS
    from scm_core.simulator import SteadyMeans, simulate_batch

    soil = SoilParams(bulk_density=1330.0)
    rig = RigConfig(slip_angle=beta, **FAST)
    one = simulate_swt(soil, rig=rig)
    many = simulate_batch([soil, soil], rigs=rig)
    assert tuple(f.name for f in fields(SteadyMeans)) == RESPONSE_KEYS
    assert one.ok and many.means.shape == (2, len(RESPONSE_KEYS)) and all(many.ok)
    expected = [getattr(one.means, k) for k in RESPONSE_KEYS]
    for row in many.means:
        assert row.tolist() == expected  # bit for bit, Fy included
    window = one.series["t"] >= rig.offset_F - 1e-9
    assert one.means.Fy == pytest.approx(float(np.mean(one.series["Fy"][window])), rel=1e-12)
    assert (one.means.Fy > 0.0) == (beta > 0.0) and (beta != 0.0 or one.means.Fy == 0.0)


def test_a_failed_batch_row_has_every_mean_nan() -> None:
    from scm_core.signals.responses import N_RESPONSES
    from scm_core.simulator import simulate_batch

    rig = RigConfig(W=5000.0, slip_angle=30.0, **FAST)  # far beyond the wheel: bottoms out
    res = simulate_batch([SoilParams(k_phi=1e5, k_c=0.0)], rigs=rig)
    assert res.status[0] != "ok" and res.means.shape == (1, N_RESPONSES)
    assert np.all(np.isnan(res.means))
