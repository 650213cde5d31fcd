"""Physical trends, plausibility of the paper's set-up, failure statuses and input validation."""

import math

import numpy as np
import pytest
from pydantic import ValidationError

from scm_core.simulator import (
    STATUS_NAMES,
    RigConfig,
    SoilParams,
    WheelGeometry,
    resolve_rig,
    simulate_batch,
    simulate_swt,
)


@pytest.fixture(scope="module")
def default_means():
    return simulate_swt().means


def test_default_run_is_plausible(default_means):
    """Paper set-up (W 315 N, slip 0.2, WF34): sinkage 1-3 cm, torque 5-30 N m, F in -50..150 N."""
    m = default_means
    assert 0.01 <= m.z <= 0.03
    assert 5.0 <= m.T <= 30.0
    assert -50.0 <= m.F <= 150.0


def test_larger_friction_angle_gives_more_drawbar_pull():
    lo, hi = simulate_batch([SoilParams(phi=25.0), SoilParams(phi=35.0)]).means
    assert hi[0] > lo[0] + 10.0  # N: tan(35)-tan(25) times W is ~80 N; demand a clear step


def test_stiffer_soil_sinks_less():
    soft, stiff = simulate_batch([SoilParams(k_phi=5e6), SoilParams(k_phi=2e7)]).means
    assert stiff[2] < soft[2] - 0.002  # m: Bekker predicts ~40 % less; demand 2 mm


def test_more_slip_more_torque_pull_and_sinkage():
    slips = (0.05, 0.2, 0.4)
    res = simulate_batch([SoilParams()] * 3, rigs=[RigConfig(slip=s) for s in slips])
    F, T, z, Fy = res.means.T  # the responses' order (scm_core.signals.responses)
    assert np.all(np.diff(F) > 0) and np.all(np.diff(T) > 0)
    assert np.all(Fy == 0.0)  # driven straight: no lateral force
    assert np.all(np.diff(z) > 0.001)  # slip sinkage: the parallel flow digs the wheel in


def test_table2_space_is_robust():
    """500 draws from Table 2's parameter space: no exception, no NaN, failures are named."""
    rng = np.random.default_rng(2024)
    n = 500
    soils = [
        SoilParams(
            k_c=rng.uniform(-1e9, 1e9),
            k_phi=rng.uniform(1.0, 1e10),
            n=rng.uniform(0.8, 2.0),
            phi=rng.uniform(11.5, 37.3),
            J=rng.uniform(0.001, 0.1),
        )
        for _ in range(n)
    ]
    wheels = [WheelGeometry(R=rng.uniform(0.125, 0.155)) for _ in range(n)]
    res = simulate_batch(soils, wheels, RigConfig(duration=25.0))
    assert set(res.status) <= set(STATUS_NAMES)
    ok = res.ok
    assert ok.sum() > 100
    assert np.isfinite(res.means[ok]).all()
    # k* = k_c / b_eff + k_phi <= 0 for every possible footprint: refused at once
    for soil, wheel, status in zip(soils, wheels, res.status, strict=True):
        b_max = 2 * wheel.outer_radius * wheel.b / (2 * wheel.outer_radius + wheel.b)
        if soil.k_c / b_max + soil.k_phi <= 0:
            assert status == "nonpositive_stiffness"


def test_failures_stop_early_with_a_named_status():
    r = simulate_swt(SoilParams(k_c=-1e9, k_phi=1.0))
    assert r.status == "nonpositive_stiffness" and r.means is None
    r = simulate_swt(SoilParams(k_phi=1e3))
    assert r.status == "bottomed_out" and r.means is None
    assert len(r.series["t"]) < 50 / r.rig.dt  # stopped early
    assert np.isfinite(r.series["z"]).all()


def test_run_shorter_than_offset_is_refused():
    with pytest.raises(ValidationError, match="averaging offset"):
        RigConfig(duration=10.0, offset_F=20.0)
    with pytest.raises(ValueError, match=r"duration: .* averaging offset 20 s"):
        resolve_rig(WheelGeometry(), RigConfig(offset_T=20.0, carriage_speed=0.05))  # 10 s run


@pytest.mark.parametrize(
    ("cls", "kwargs", "field"),
    [
        (SoilParams, {"n": -1.0}, "n"),
        (SoilParams, {"phi": 95.0}, "phi"),
        (WheelGeometry, {"R": -0.1}, "R"),
        (RigConfig, {"slip": 1.0}, "slip"),
        (RigConfig, {"shear": "bogus"}, "shear"),
        (RigConfig, {"dt": math.nan}, "dt"),
    ],
)
def test_invalid_values_name_the_field(cls, kwargs, field):
    with pytest.raises(ValidationError) as err:
        cls(**kwargs)
    assert err.value.errors()[0]["loc"][0] == field


def test_defaults_are_the_papers_set_up():
    w, s = WheelGeometry(), SoilParams()
    r = resolve_rig(w, RigConfig())
    assert (w.R, w.b, w.n_grousers, w.grouser_height) == (0.125, 0.112, 12, 0.009)
    assert (r.W, r.duration, r.offset_F, r.offset_T, r.offset_z) == (315.0, 50.0, 20.0, 20.0, 1.0)
    assert (r.dx, r.dt, r.max_sinkage, r.omega) == (0.005, 0.02, 0.1, 0.1)
    assert r.slip == pytest.approx(0.2) and r.carriage_speed == pytest.approx(0.01)
    assert (s.c, s.phi, s.n, s.k_c, s.J) == (0.0, 30.0, 1.1, 0.0, 0.001)
    assert s.k_c / 0.04 + s.k_phi == pytest.approx(1e7)


def test_skid_runs_longer_and_the_sinkage_window_can_follow_f():
    """In skid the carriage travels 4 r (1 + |s|): the bow wave and the slip sinkage build
    over a longer travel (a locked wheel 8 r); offset_z_fraction sets z's window."""
    w = WheelGeometry()
    drive = resolve_rig(w, RigConfig(slip=0.5, carriage_speed=0.01))
    half = resolve_rig(w, RigConfig(slip=-0.5, slip_convention="symmetric", carriage_speed=0.01))
    locked = resolve_rig(w, RigConfig(omega=0.0, carriage_speed=0.01))
    assert drive.duration == 50.0 and half.duration == 75.0 and locked.duration == 100.0
    assert (locked.offset_F, locked.offset_z) == (40.0, 2.0)
    own = resolve_rig(w, RigConfig(omega=0.0, carriage_speed=0.01, offset_z_fraction=0.4))
    assert own.offset_z == own.offset_F == 40.0
    assert (
        resolve_rig(w, RigConfig(slip=-1.0, slip_convention="symmetric", duration=30.0)).duration
        == 30.0
    )


def test_same_inputs_same_outputs():
    a, b = simulate_swt(), simulate_swt()
    np.testing.assert_array_equal(a.series["F"], b.series["F"])
    batch = simulate_batch([SoilParams()])
    assert batch.means[0, 0] == a.means.F
