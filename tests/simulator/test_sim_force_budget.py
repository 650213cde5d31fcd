"""The force budget (swt.ForceBudget): the steady drawbar pull and lateral force split by
mechanism. Checked by what must hold whatever the soil: the parts add up to the forces the run
reports, a straight wheel has no lateral part, a soil without weight no bow-wave wedge and no
side force, a mirrored slip angle mirrors the lateral parts only, and the signs follow the
kinematics (a locked wheel's shear drags it back, a driven wheel's pushes it on; the soil
pressed ahead of a wheel resists it)."""

from __future__ import annotations

import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_swt

#: a CMU-sized smooth wheel in a dry sand with weight (the bow wave and the side push soil)
SAND = SoilParams(k_phi=2.9e6, k_c=0.0, n=1.3, c=0.0, phi=34.0, J=0.01, K=3.5e6,
                  repose_angle=29.0, bulk_density=1330.0)  # fmt: skip
WHEEL = WheelGeometry(R=0.058, b=0.05, n_grousers=0)


def _run(beta: float, rim: float):
    rig = RigConfig(W=20.0, omega=rim / WHEEL.R, carriage_speed=0.01, slip_angle=beta,
                    duration=16.0, offset_F=8.0, offset_T=8.0, offset_z=8.0)  # fmt: skip
    r = simulate_swt(SAND, WHEEL, rig)
    assert r.ok, r.status
    return r


def _assert_adds_up(r) -> None:
    b, m = r.budget, r.means
    assert b.F_normal + b.F_shear + b.F_cap + b.F_heap == pytest.approx(m.F, abs=1e-9)
    assert b.Fy_shear + b.Fy_side == pytest.approx(m.Fy, abs=1e-9)


def test_paper_default_driven_wheel() -> None:
    """The paper's SWT (driven at slip 0.2, weightless soil): the shear's thrust less the
    normal stresses' compaction resistance is the pull; nothing sideways, no bow-wave wedge."""
    r = simulate_swt()
    b = r.budget
    _assert_adds_up(r)
    assert b.F_shear > 0.0 > b.F_normal
    assert b.F_heap == 0.0 and b.Fy_shear == 0.0 and b.Fy_side == 0.0
    assert b.F_cap <= 0.0


def test_locked_straight_wheel_in_sand() -> None:
    """A locked wheel: its shear drags it back, the soil pressed ahead resists, and the heap it
    pushes weighs on its front; still nothing sideways."""
    r = _run(0.0, 0.0)
    b = r.budget
    _assert_adds_up(r)
    assert b.F_shear < 0.0 and b.F_normal < 0.0 and b.F_heap < 0.0
    assert b.Fy_shear == 0.0 and b.Fy_side == 0.0


def test_steered_wheel_mirrors() -> None:
    """At +-60 deg the drawbar pull's parts are the same and the lateral ones opposite; the
    leading side pushes soil (its force against the side slip, the same sign as Fy). To 2e-3
    of the load (0.04 N), as the forces themselves (test_sim_steering: the two images sum their
    rows in different orders, which a node loaded in one image and not the other amplifies;
    the heap's height is a maximum over the rows, 0.001 N apart here)."""
    tol = 2e-3 * 20.0
    plus, minus = _run(60.0, 0.0), _run(-60.0, 0.0)
    for r in (plus, minus):
        _assert_adds_up(r)
    bp, bm = plus.budget, minus.budget
    for name in ("F_normal", "F_shear", "F_cap", "F_heap"):
        assert getattr(bp, name) == pytest.approx(getattr(bm, name), abs=tol), name
    assert bp.Fy_shear == pytest.approx(-bm.Fy_shear, abs=tol)
    assert bp.Fy_side == pytest.approx(-bm.Fy_side, abs=tol)
    assert bp.Fy_side > 0.0 and bp.Fy_shear > 0.0 and plus.means.Fy > 0.0


def test_weightless_soil_has_no_side_force() -> None:
    """The side's passive force is the weight of the wedge it lifts (c = 0): none without it."""
    soil = SAND.model_copy(update={"bulk_density": 0.0})
    rig = RigConfig(W=20.0, omega=0.0, carriage_speed=0.01, slip_angle=45.0, duration=16.0,
                    offset_F=8.0, offset_T=8.0, offset_z=8.0)  # fmt: skip
    r = simulate_swt(soil, WHEEL, rig)
    assert r.ok
    _assert_adds_up(r)
    assert r.budget.Fy_side == 0.0 and r.budget.F_heap == 0.0
    assert r.budget.Fy_shear == r.means.Fy


def test_no_budget_without_steady_means() -> None:
    """A run that does not finish has no steady means, and so no budget."""
    soil = SAND.model_copy(update={"k_phi": 2e3})
    rig = RigConfig(W=20.0, omega=0.0, carriage_speed=0.01, duration=16.0, offset_F=8.0,
                    offset_T=8.0, offset_z=8.0)  # fmt: skip
    r = simulate_swt(soil, WHEEL, rig)
    assert r.status != "ok" and r.means is None and r.budget is None


@pytest.mark.parametrize("slip", [0.2, -0.3])
def test_normal_stresses_pay_the_compaction_by_the_mean_cosine(slip: float) -> None:
    """Energy. A rigid wheel pressing Bekker soil (no flows, no taper) does plastic work on the
    nodes its front face presses down: a node at the front angle theta sinks by v tan(theta)
    per second under sigma, on its projected area dA. Eq. (9) puts sigma on dA along the
    surface normal, whose part along the heading is sin(theta): the normal stresses pay
    sigma v sin(theta) dA of the sigma v tan(theta) dA, cos(theta) of it. With sigma = k
    (R (cos(theta) - cos(theta_f)))^n over the front arc 0..theta_f (cos(theta_f) = 1 - z / R),
    the sigma-weighted share is, in closed form, 1 - z / ((n + 2) R) (0.937 for the paper's
    soil and a 125 mm smooth wheel at 24 mm). To 0.012 at the default dx and dt, and closer
    under dx / 2, dt / 2 (the yield stress at each step's end times the step's increment is an
    upper sum of the work)."""
    soil = SoilParams(k_phi=3e6, K=1e9)
    wheel = WheelGeometry(n_grousers=0)
    conv = {"slip_convention": "symmetric"} if slip < 0 else {}
    gaps = []
    for f in (1, 2):
        rig = RigConfig(slip=slip, bulldozing=False, border_taper=False, duration=30.0,
                        offset_F=15.0, offset_T=15.0, offset_z=15.0, dx=0.005 / f,
                        dt=0.02 / f, **conv)  # fmt: skip
        r = simulate_swt(soil, wheel, rig)
        assert r.ok
        closed = 1.0 - r.means.z / ((soil.n + 2.0) * wheel.R)
        gaps.append(abs(r.budget.compaction_paid - closed))
    assert gaps[0] < 0.012
    assert gaps[1] < gaps[0]


def test_a_wheel_dragged_sideways_pays_nothing_for_what_it_compacts() -> None:
    """The z-buffer's surface has no normal along the axle: a wheel dragged along it compacts
    the soil it slides onto (plastic work) while its normal stresses push nothing along the
    travel. The budget says so (issue 70's 90 deg gap; docs/steering.md)."""
    r = _run(90.0, 0.0)
    b = r.budget
    assert b.compaction_power > 0.0
    assert b.v_heading == 0.0 and b.compaction_paid == 0.0
