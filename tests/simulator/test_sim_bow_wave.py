"""The bow wave's weight on the wheel (``SoilParams.bulk_density`` > 0).

SCM's deposits are weightless; with a bulk density the loose soil heaped ahead of the wheel
resists with Rankine's passive pressure: its own wedge, 0.5 K_p gamma h^2 per width (Bekker's
bulldozing resistance with c = 0), and its weight as a surcharge K_p gamma h on the face below
its base. Checks from soil mechanics, not from the code: Rankine's coefficients in closed form,
a locked wheel's extra braking between the heap's wedge alone (less what the surcharge's lift
takes off the Bekker face) and the passive force of a soil wall as deep as the whole face, and a
driven wheel, which pushes no heap ahead, left alone.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_swt
from scm_core.simulator.deformation import bow_wave, heap_passive_pressure, passive_coefficient
from scm_core.simulator.state import Ground

G = 9.81
RHO = 1330.0  # the CMU sand (kg/m^3)


@pytest.mark.parametrize(
    ("phi", "k_p"),
    [(0.0, 1.0), (30.0, 3.0), (45.0, (1 + math.sqrt(0.5)) / (1 - math.sqrt(0.5)))],
)
def test_rankine_passive_coefficient(phi, k_p):
    assert passive_coefficient(math.tan(math.radians(phi))) == pytest.approx(k_p, rel=1e-12)


def test_heap_pressure_is_rankine_with_the_loose_soil_at_its_angle_of_repose():
    gamma, h = RHO * G, 0.02
    sigma_q, f_b = heap_passive_pressure(gamma, math.tan(math.radians(30.0)), 1.0, h)
    assert sigma_q == pytest.approx(3.0 * gamma * h, rel=1e-12)  # K_p(30 deg) = 3
    assert f_b == pytest.approx(0.5 * (1 + math.sqrt(0.5)) / (1 - math.sqrt(0.5)) * gamma * h * h)


def _ground(nx: int = 30, ny: int = 6) -> Ground:
    z = np.zeros((nx, ny))
    return Ground(z.copy(), z.copy(), z.copy(), z.copy(), z.copy(), z.copy())


def test_bow_wave_is_the_mean_over_rows_of_the_thickest_loose_soil_ahead():
    g = _ground()
    g.h0[:] = -0.004  # the ground's level, lowered by 4 mm
    g.hl[12, 1:5] = 0.010  # a ridge 10 mm high ahead of the axle (column 10)
    g.hl[14, 1:3] = 0.020  # higher on two of the four rows
    g.hl[5, 1:5] = 0.050  # behind the axle: not ahead
    g.hl[25, 1:5] = 0.050  # beyond the columns looked at
    h, base = bow_wave(g, 10, 8, 1, 4, 1.0)
    assert h == pytest.approx((0.020 + 0.020 + 0.010 + 0.010) / 4, rel=1e-12)
    assert base == pytest.approx(-0.004, rel=1e-12)
    h_capped, _ = bow_wave(g, 10, 8, 1, 4, 0.006)  # the rim's top 10 mm above the base
    assert h_capped == pytest.approx(0.010, rel=1e-12)
    assert bow_wave(_ground(), 10, 8, 1, 4, 1.0)[0] == 0.0


def _rig(slip: float) -> RigConfig:
    return RigConfig(
        W=20.0,
        slip=slip,
        slip_convention="symmetric",
        carriage_speed=0.01,
        shear="displacement",
        skid_ploughing="sliding_face",
        offset_z_fraction=0.4,
    )


def test_a_locked_wheel_brakes_harder_by_its_heaps_passive_pressure_and_a_driven_one_not():
    """CMU-sized smooth wheel (58 mm, 50 mm wide, 20 N) on a sand like the CMU one."""
    phi, repose = 34.0, 29.0
    base = dict(k_phi=3e6, n=1.3, phi=phi, J=0.01, K=4.5e6, shear_band=0.017, repose_angle=repose)
    wheel = WheelGeometry(R=0.058, b=0.05, n_grousers=0)
    runs = {
        (slip, rho): simulate_swt(SoilParams(**base, bulk_density=rho), wheel, _rig(slip))
        for slip in (-1.0, 0.5)
        for rho in (0.0, RHO)
    }
    assert all(r.ok for r in runs.values())
    heavy = runs[-1.0, RHO]
    h = heavy.diagnostics["bow_wave_height"]
    assert 0.005 < h < 0.06  # a heap of centimetres ahead of the locked wheel
    gamma, b = RHO * G, 0.05
    wedge = 0.5 * passive_coefficient(math.tan(math.radians(repose))) * gamma * h * h * b
    assert heavy.diagnostics["bow_wave_force"] == pytest.approx(wedge, rel=1e-9)
    # the surcharge lifts the wheel a little, which takes some Bekker face pressure off: more
    # than half the wedge remains; at most a wall as deep as the whole face fails passively
    k_p = passive_coefficient(math.tan(math.radians(phi)))
    wall = 0.5 * k_p * gamma * (h + heavy.means.z) ** 2 * b
    extra = runs[-1.0, 0.0].means.F - heavy.means.F
    assert 0.5 * wedge < extra < wall
    # a driven wheel leaves its soil behind: no heap to push, the same within 1 % of the load
    assert runs[0.5, RHO].diagnostics["bow_wave_height"] < 0.002
    assert abs(runs[0.5, RHO].means.F - runs[0.5, 0.0].means.F) < 0.01 * 20.0


@pytest.mark.parametrize("rho", [-1.0, 5001.0])
def test_a_bulk_density_outside_its_range_is_refused_naming_the_field(rho):
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="bulk_density"):
        SoilParams(bulk_density=rho)


def test_a_case_with_a_negative_bulk_density_stops_before_anything_is_written(tmp_path):
    """The CLI's message names the case's field; no results folder is made."""
    from click.testing import CliRunner

    from services.cli.main import cli

    case = Path(__file__).resolve().parents[2] / "examples" / "cmu_joint.toml"
    text = case.read_text().replace("bulk_density = 1330.0", "bulk_density = -5.0")
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('    "cmu_', f'    "{case.parent}/cmu_'))  # the data, absolute
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["calibrate", str(bad), "--out", str(out)])
    assert res.exit_code != 0
    assert "nominal.bulk_density" in res.output and "Traceback" not in res.output
    assert not out.exists()
