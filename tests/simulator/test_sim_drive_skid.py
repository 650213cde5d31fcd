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

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_batch

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
    means = res.means.reshape(len(pairs), k, 3)
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
def test_skid_brakes_and_sinks_more_as_it_grows(wheel, load, k_range):
    """Skids of 0.2 and 0.5 and a locked wheel (lab convention) on 10 synthetic sands: drawbar
    pull negative and falling, sinkage growing (the bow wave is loose soil pushed ahead, which
    the wheel does not climb). A soft soil may bury the wheel: a named failure, at most 3."""
    soils = sand_like_soils(10, seed=11, k_range=k_range)
    rigs = [
        RigConfig(W=load, slip=s, slip_convention="symmetric", carriage_speed=0.01)
        for _ in soils
        for s in SKIDS
    ]
    res = simulate_batch([s for s in soils for _ in SKIDS], wheel, rigs)
    assert set(res.status) <= {"ok", "bottomed_out"}
    ok = res.ok.reshape(len(soils), len(SKIDS)).all(axis=1)
    assert ok.sum() >= 7
    means = res.means.reshape(len(soils), len(SKIDS), 3)[ok]
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
    m = res.means.reshape(len(kappas), len(slips), 3)
    F, z = m[:, :2, 0], m[:, :2, 2]  # skids: rows kappa, columns locked / 0.5
    assert np.all(np.diff(z, axis=0) > 0)  # more ploughing, deeper
    assert np.all(np.diff(F, axis=0) < 0)  # and more braking
    assert np.mean(z[-1] / z[0]) > 1.1  # clearly so: the option is not a rounding error
    np.testing.assert_array_equal(m[1:, 2], np.repeat(m[:1, 2], 2, axis=0))  # drive untouched
    plain = simulate_batch([SoilParams(**base)], wheel, rigs[0])
    np.testing.assert_array_equal(plain.means[0], m[0, 0])


def test_mobilised_digging_saturates_with_the_shear_and_leaves_skid_alone():
    """A driven smooth wheel digs itself in through the layer its rim drags (docs/simulator.md
    step 5). Thinning (continuity of the accelerated layer) digs at most the layer depth times
    the slip; 'mobilised' digs the depth in which the shear is mobilised (Janosi's displacement
    x |u| / v along the contact), so the slip sinkage saturates with the shear, by slip ~0.75
    for J = 15 mm, as the CMU smooth wheel's does (increments over the zero-slip sinkage 3.5,
    8.3, 11.0, 11.3 mm at 0.23, 0.5, 0.75, 0.9: 73 % of the 0.9 value at 0.5). Both dig no
    deeper than the layer; the mobilised law is continuous through zero slip, and a skidding
    wheel is the same under both (bit-identical)."""
    wheel = WheelGeometry(R=0.058, b=0.05, n_grousers=0)
    layer = 0.015
    soil = SoilParams(k_phi=5e6, n=1.2, phi=30.0, J=0.015, shear_band=layer)
    slips = (-0.01, 0.0, 0.01, 0.25, 0.5, 0.9, -0.5)
    laws = ("thinning", "mobilised")
    rigs = [
        RigConfig(
            W=22.0,
            slip=s,
            slip_convention="symmetric",
            carriage_speed=0.01,
            shear="displacement",
            drive_digging=law,
        )
        for law in laws
        for s in slips
    ]
    res = simulate_batch([soil] * len(rigs), wheel, rigs)
    assert res.ok.all()
    m = res.means.reshape(len(laws), len(slips), 3)
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
