"""Drive and skid on synthetic soils: bounds from soil mechanics and the trends real wheels show.

* Driving: drawbar pull cannot exceed the Coulomb strength of the soil under the wheel,
  c A + W tan(phi) (Micklethwaite's maximum tractive effort; Bekker 1969), however hard the
  wheel spins: soil left behind it must not push it forward.
* Skid (lab convention (v_rim - v)/max(v, v_rim), -1 locked): a braked wheel pushes soil ahead,
  sinks and brakes, more so as the skid grows (Wong & Reece 1967, part II).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from scm_core.signals.responses import N_RESPONSES
from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_batch
from scm_core.simulator.layer import sliding_face_height

DRIVE_SLIPS = (0.1, 0.5, 0.95)
SKIDS = (-0.2, -0.5, -1.0)
W = 315.0


def table2_soils(n: int, seed: int) -> list[tuple[SoilParams, WheelGeometry]]:
    """Draws from Table 2's parameter space (k_c, k_phi, n, phi, J, R), c = 0."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        soil = SoilParams(
            k_c=rng.uniform(-1e9, 1e9),
            k_phi=rng.uniform(1.0, 1e10),
            n=rng.uniform(0.8, 2.0),
            phi=rng.uniform(11.5, 37.3),
            J=rng.uniform(0.001, 0.1),
        )
        out.append((soil, WheelGeometry(R=rng.uniform(0.125, 0.155))))
    return out


def run_all(pairs, slips, **rig):
    soils = [s for s, _ in pairs for _ in slips]
    wheels = [w for _, w in pairs for _ in slips]
    rigs = [
        RigConfig(
            W=W, slip=s, slip_convention="symmetric", carriage_speed=0.01, duration=25.0, **rig
        )
        for _ in pairs
        for s in slips
    ]
    res = simulate_batch(soils, wheels, rigs)
    k = len(slips)
    means = res.means.reshape(len(pairs), k, N_RESPONSES)
    ok = res.ok.reshape(len(pairs), k).all(axis=1)
    return means, ok


@pytest.fixture(scope="module")
def random_soils():
    """20 soils of Table 2's space that run ok at every slip (drawn from 40)."""
    pairs = table2_soils(40, seed=8)
    means, ok = run_all(pairs, DRIVE_SLIPS)
    keep = np.flatnonzero(ok)[:20]
    assert keep.size == 20
    return [pairs[i] for i in keep], means[keep]


def test_drawbar_pull_stays_below_the_coulomb_strength_of_the_soil(random_soils):
    """DP <= c A + W tan(phi) + 2 % of W at driving slips 0.1 to 0.95 (c = 0 here)."""
    pairs, means = random_soils
    for (soil, _), m in zip(pairs, means, strict=True):
        bound = W * math.tan(math.radians(soil.phi)) + 0.02 * W
        assert np.all(m[:, 0] <= bound), (soil.phi, m[:, 0], bound)


def sand_like_soils(n: int, seed: int, k_range: tuple[float, float]) -> list[SoilParams]:
    """Synthetic sands: k* log-uniform in k_range (k_c = 0), n 0.7-1.3, phi 25-40 deg,
    J 1-10 mm/s (log-uniform)."""
    rng = np.random.default_rng(seed)
    return [
        SoilParams(
            k_phi=10 ** rng.uniform(*np.log10(k_range)),
            n=rng.uniform(0.7, 1.3),
            phi=rng.uniform(25.0, 40.0),
            J=10 ** rng.uniform(-3.0, -2.0),
        )
        for _ in range(n)
    ]


@pytest.mark.parametrize(
    ("wheel", "load", "k_range"),
    [
        (WheelGeometry(), W, (1e6, 3e7)),  # the paper's grousered wheel, 315 N
        (WheelGeometry(R=0.058, b=0.05, n_grousers=0), 22.0, (2e5, 2e7)),  # a small smooth one
    ],
    ids=["paper-wheel", "small-smooth-wheel"],
)
@pytest.mark.parametrize("ploughing", ["kappa", "sliding_face"])
def test_skid_brakes_and_sinks_more_as_it_grows(wheel, load, k_range, ploughing):
    """Skids of 0.2 and 0.5 and a locked wheel (lab convention) on 10 synthetic sands: drawbar
    pull negative and falling, sinkage growing (the bow wave is loose soil pushed ahead, which
    the wheel does not climb), with either skid ploughing law. A soft soil may bury the wheel:
    a named failure, at most 3."""
    soils = sand_like_soils(10, seed=11, k_range=k_range)
    rigs = [
        RigConfig(
            W=load,
            slip=s,
            slip_convention="symmetric",
            carriage_speed=0.01,
            skid_ploughing=ploughing,
        )
        for _ in soils
        for s in SKIDS
    ]
    res = simulate_batch([s for s in soils for _ in SKIDS], wheel, rigs)
    assert set(res.status) <= {"ok", "bottomed_out"}
    ok = res.ok.reshape(len(soils), len(SKIDS)).all(axis=1)
    assert ok.sum() >= 7
    means = res.means.reshape(len(soils), len(SKIDS), N_RESPONSES)[ok]
    F, z = means[:, :, 0], means[:, :, 2]
    assert np.all(F < 0)
    assert np.all(np.diff(F, axis=1) < 0)  # more skid, more braking
    assert np.all(np.diff(z, axis=1) > -1e-4)  # more skid, more sinkage (0.1 mm: grid level)
    assert np.mean(z[:, -1] / z[:, 0]) > 1.05  # and clearly so on average


def test_plain_scm_brakes_more_as_the_skid_grows():
    """The paper's SCM (no extension) on its own set-up: braking grows with skid too."""
    res = simulate_batch(
        [SoilParams()] * 3,
        rigs=[RigConfig(slip=s, slip_convention="symmetric", carriage_speed=0.01) for s in SKIDS],
    )
    F, z = res.means[:, 0], res.means[:, 2]
    assert np.all(F < 0) and np.all(np.diff(F) < 0)
    assert np.all(np.diff(z) > 0)


def test_locked_wheel_simulates():
    res = simulate_batch(
        [SoilParams()], rigs=[RigConfig(omega=0.0, carriage_speed=0.01, duration=25.0)]
    )
    assert res.status == ["ok"] and res.means[0, 0] < 0 and 0.01 < res.means[0, 2] < 0.1


def test_ploughing_deepens_and_brakes_a_skid_and_leaves_drive_alone():
    """Ploughing (a skidding wheel's front face pushes soil ahead as a blade, Wong & Reece 1967
    part II): on a small smooth wheel in sand, the locked wheel and a 0.5 skid sink deeper and
    brake harder as kappa grows; a driven wheel is untouched (bit-identical), and kappa = 0 is
    the model without the option."""
    wheel = WheelGeometry(R=0.058, b=0.05, n_grousers=0)
    kappas = (0.0, 0.2, 0.4)  # kappa 0.5 digs this locked wheel in to its rim (bottomed out)
    slips = (-1.0, -0.5, 0.5)
    base = dict(k_phi=5e6, n=1.2, phi=30.0, J=0.015)
    soils = [SoilParams(**base, ploughing=k) for k in kappas for _ in slips]
    rigs = [
        RigConfig(W=22.0, slip=s, slip_convention="symmetric", carriage_speed=0.01)
        for _ in kappas
        for s in slips
    ]
    res = simulate_batch(soils, wheel, rigs)
    assert res.ok.all()
    m = res.means.reshape(len(kappas), len(slips), N_RESPONSES)
    F, z = m[:, :2, 0], m[:, :2, 2]  # skids: rows kappa, columns locked / 0.5
    assert np.all(np.diff(z, axis=0) > 0)  # more ploughing, deeper
    assert np.all(np.diff(F, axis=0) < 0)  # and more braking
    assert np.mean(z[-1] / z[0]) > 1.1  # clearly so: the option is not a rounding error
    np.testing.assert_array_equal(m[1:, 2], np.repeat(m[:1, 2], 2, axis=0))  # drive untouched
    plain = simulate_batch([SoilParams(**base)], wheel, rigs[0])
    np.testing.assert_array_equal(plain.means[0], m[0, 0])


def small_wheel_means(soil: SoilParams, slips, variants: list[dict]) -> np.ndarray:
    """Steady means (variant, slip, F/T/z) of the CMU-sized smooth wheel (R 58 mm, b 50 mm, 22 N,
    10 mm/s, displacement form) on ``soil`` at lab-convention ``slips``, one row per set of
    simulator options in ``variants``; every run must be ok."""
    wheel = WheelGeometry(R=0.058, b=0.05, n_grousers=0)
    rigs = [
        RigConfig(
            W=22.0,
            slip=s,
            slip_convention="symmetric",
            carriage_speed=0.01,
            shear="displacement",
            **options,
        )
        for options in variants
        for s in slips
    ]
    res = simulate_batch([soil] * len(rigs), wheel, rigs)
    assert res.ok.all(), res.status
    return res.means.reshape(len(variants), len(slips), N_RESPONSES)


def test_mobilised_digging_saturates_with_the_shear_and_leaves_skid_alone():
    """A driven smooth wheel digs itself in through the layer its rim drags (docs/simulator.md
    step 5). Thinning (continuity of the accelerated layer) digs at most the layer depth times
    the slip; 'mobilised' digs the depth in which the shear is mobilised (Janosi's displacement
    x |u| / v along the contact), so the slip sinkage saturates with the shear, by slip ~0.75
    for J = 15 mm, as the CMU smooth wheel's does (increments over the zero-slip sinkage 3.5,
    8.3, 11.0, 11.3 mm at 0.23, 0.5, 0.75, 0.9: 73 % of the 0.9 value at 0.5). Both dig no
    deeper than the layer; the mobilised law is continuous through zero slip, and a skidding
    wheel is the same under both (bit-identical)."""
    layer = 0.015
    soil = SoilParams(k_phi=5e6, n=1.2, phi=30.0, J=0.015, shear_band=layer)
    slips = (-0.01, 0.0, 0.01, 0.25, 0.5, 0.9, -0.5)
    laws = ("thinning", "mobilised")
    m = small_wheel_means(soil, slips, [{"drive_digging": law} for law in laws])
    z = m[:, :, 2]
    np.testing.assert_array_equal(m[0, -1], m[1, -1])  # skid untouched
    dig = z[:, 3:6] - z[:, 1:2]  # sinkage over the zero-slip sinkage at 0.25, 0.5, 0.9
    assert np.all(np.diff(dig, axis=1) > 0)  # both dig deeper as the slip grows
    assert np.all(dig[1] > dig[0])  # the mobilised law digs deeper than continuity allows
    assert np.all(dig < layer)  # neither deeper than the dragged layer
    share = dig[:, 1] / dig[:, 2]  # how much of the 0.9 slip's digging is done at 0.5
    assert share[0] < 0.5 < 0.6 < share[1]  # continuity: late; mobilised: early, as measured
    # continuous through zero slip: neighbouring slips 0.01 apart differ by well under 1 mm
    # (the jump a drive/skid switch of the dug depth would give: layer * f ~ 1 mm)
    assert np.all(np.abs(np.diff(z[1, :3])) < 0.3e-3)


@pytest.mark.parametrize("phi", [20.0, 30.0, 40.0])
def test_sliding_face_height_is_where_the_rim_leaves_the_friction_cone(phi):
    """The sliding part of a skidding wheel's front face (docs/simulator.md step 5) ends where
    the rim's velocity over the ground lies on the friction cone of angle phi: tangential
    v cos(theta) - omega r = tan(phi) times normal v sin(theta). Rolling: no sliding zone;
    locked: theta_s = 90 deg - phi, height r (1 - sin phi); it rises with the skid."""
    r, v = 0.058, 0.01
    tan_phi = math.tan(math.radians(phi))
    assert sliding_face_height(v, v / r, r, tan_phi) == 0.0  # rolling
    assert sliding_face_height(v, 2 * v / r, r, tan_phi) == 0.0  # driven
    locked = sliding_face_height(v, 0.0, r, tan_phi)
    assert locked == pytest.approx(r * (1.0 - math.sin(math.radians(phi))), rel=1e-12)
    heights = []
    for skid in (0.1, 0.3, 0.5, 0.7, 0.9):
        omega = (1.0 - skid) * v / r
        y = sliding_face_height(v, omega, r, tan_phi)
        theta = math.acos(1.0 - y / r)
        tangential = v * math.cos(theta) - omega * r
        assert tangential == pytest.approx(tan_phi * v * math.sin(theta), rel=1e-9)
        heights.append(y)
    assert np.all(np.diff(heights) > 0) and heights[-1] < locked


def test_sliding_face_ploughing_sinks_a_skid_with_its_square_and_leaves_drive_alone():
    """With the dragged layer of a skidding wheel set by its sliding face (no parameter), a
    small smooth wheel in sand sinks little at small skids and fast at large ones, as measured
    (CMU smooth wheel: 9, 36 mm over the zero-slip sinkage at -0.5 and locked, Wong & Reece 1967
    part II: sinkage grows rapidly towards the locked wheel): the sinkage gained from -0.5 to
    the locked wheel is over twice that from 0 to -0.5 (the calibrated band's fixed layer: under
    twice); braking grows with the skid, and a driven wheel is untouched (bit-identical)."""
    soil = SoilParams(k_phi=5e6, n=1.2, phi=30.0, J=0.012, shear_band=0.015)
    slips = (0.0, -0.2, -0.5, -0.7, -1.0, 0.5)
    laws = ("kappa", "sliding_face")
    m = small_wheel_means(
        soil, slips, [{"drive_digging": "mobilised", "skid_ploughing": law} for law in laws]
    )
    np.testing.assert_array_equal(m[0, [0, -1]], m[1, [0, -1]])  # rolling and drive untouched
    F, z = m[:, 1:5, 0], m[:, :5, 2]
    assert np.all(np.diff(F, axis=1) < 0)  # more skid, more braking
    gain_small = z[:, 2] - z[:, 0]  # from rolling to the 0.5 skid
    gain_large = z[:, 4] - z[:, 2]  # from the 0.5 skid to the locked wheel
    assert gain_large[1] > 2.0 * gain_small[1]
    assert gain_large[0] < 2.0 * gain_small[0]
    assert np.all(np.diff(z[1, 1:]) > 0)
