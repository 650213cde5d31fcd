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
