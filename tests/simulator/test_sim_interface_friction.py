"""Friction of the soil on the wheel's surface, tan(delta) = interface_friction * tan(phi).

A smooth rim shears the soil on its own surface, whose friction angle delta is below the soil's
internal phi (Coulomb's wall friction; Bekker 1969, Wong 2010: grousers raise traction by moving
the failure surface into the soil, which shears at phi). Checks that do not come from the code:
a rigid wheel spinning on a soil too stiff to sink in slides like a block, so its drawbar pull
and its torque over the radius are Coulomb's tan(delta) times the load (to the few tenths of a
percent that its 0.14 mm sinkage tilts the contact); soil trapped between grousers shears on
soil, so the tip-circle contact takes phi whatever the rim's friction.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_batch
from scm_core.simulator.layout import P_TANDELTA, pack

W, R = 22.0, 0.058


def test_a_rim_sliding_on_a_stiff_soil_pulls_and_turns_with_coulomb_friction():
    ratios = (0.5, 0.75, 1.0)
    soils = [
        SoilParams(k_phi=5e8, n=1.0, phi=30.0, J=0.001, shear_band=0.0, interface_friction=m)
        for m in ratios
    ]
    rig = RigConfig(
        W=W, slip=0.9, slip_convention="symmetric", carriage_speed=0.01, shear="displacement"
    )
    res = simulate_batch(soils, WheelGeometry(R=R, b=0.05, n_grousers=0), [rig] * 3)
    assert res.ok.all()
    assert np.all(res.means[:, 2] < 0.2e-3)  # the block hardly sinks
    tan_delta = np.array(ratios) * math.tan(math.radians(30.0))
    np.testing.assert_allclose(res.means[:, 0] / W, tan_delta, rtol=0.01)  # drawbar pull
    np.testing.assert_allclose(res.means[:, 1] / (W * R), tan_delta, rtol=0.01)  # torque


@pytest.mark.parametrize("ratio", [0.3, 1.0])
def test_the_tip_circle_shears_soil_on_soil(ratio):
    soil = SoilParams(phi=32.0, interface_friction=ratio)
    grousered = WheelGeometry(R=R, b=0.05, n_grousers=12, grouser_height=0.005)
    trapped = pack(soil, grousered, RigConfig(grouser_contact="tip_circle"))
    faces = pack(soil, grousered, RigConfig())
    assert trapped[P_TANDELTA] == soil.tan_phi
    assert faces[P_TANDELTA] == pytest.approx(ratio * soil.tan_phi, rel=1e-15)


def _cmu(slip: float, stuck: str) -> RigConfig:
    return RigConfig(
        W=W,
        slip=slip,
        slip_convention="symmetric",
        carriage_speed=0.01,
        shear="displacement",
        skid_ploughing="sliding_face",
        stuck_shear=stuck,
    )


SAND = {"k_phi": 5e6, "n": 1.2, "phi": 30.0, "J": 0.008, "shear_band": 0.015}


def test_stuck_soil_changes_nothing_when_the_rim_is_as_rough_as_the_soil():
    """With delta = phi the soil that moves with the rim shears at the same angle either way:
    skid, rolling and drive give the same bits."""
    wheel = WheelGeometry(R=R, b=0.05, n_grousers=0)
    soils = [SoilParams(**SAND)] * 6
    rigs = [_cmu(s, m) for s in (-0.5, 0.0, 0.5) for m in ("interface", "soil")]
    res = simulate_batch(soils, wheel, rigs)
    assert res.ok.all()
    np.testing.assert_array_equal(res.means[0::2], res.means[1::2])


def test_a_sliding_rim_keeps_coulombs_friction_with_stuck_soil():
    """Where the rim slides (a wheel spinning on a soil too stiff to sink: its velocity lies
    outside the friction cone everywhere) the interface's delta still acts: Coulomb's
    tan(delta) W, as without the option."""
    soil = SoilParams(k_phi=5e8, n=1.0, phi=30.0, J=0.001, shear_band=0.0, interface_friction=0.5)
    rig = RigConfig(
        W=W, slip=0.9, slip_convention="symmetric", carriage_speed=0.01, shear="displacement",
        stuck_shear="soil",
    )  # fmt: skip
    res = simulate_batch([soil], WheelGeometry(R=R, b=0.05, n_grousers=0), [rig])
    tan_delta = 0.5 * math.tan(math.radians(30.0))
    assert res.means[0, 0] / W == pytest.approx(tan_delta, rel=0.01)


def test_a_locked_rim_brakes_harder_where_its_wedge_shears_the_soil():
    """A locked smooth rim of friction delta < phi: the soil ahead of the upper front face
    moves with the rim (its velocity, into the soil, lies inside the friction cone), so with
    stuck_shear 'soil' that part shears at phi and the wheel brakes harder than with delta
    everywhere, and no harder than a rim as rough as the soil (delta = phi everywhere)."""
    wheel = WheelGeometry(R=R, b=0.05, n_grousers=0)
    smooth = SoilParams(**SAND, interface_friction=0.6)
    rough = SoilParams(**SAND)
    res = simulate_batch(
        [smooth, smooth, rough],
        wheel,
        [_cmu(-1.0, "interface"), _cmu(-1.0, "soil"), _cmu(-1.0, "interface")],
    )
    assert res.ok.all()
    sliding, wedge, soil_on_soil = res.means[:, 0]
    assert soil_on_soil < wedge < sliding - 0.5  # N: braking is negative
