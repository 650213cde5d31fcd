"""Grousers as trapped soil (``grouser_contact = "tip_circle"``, docs/simulator.md step 1).

The soil between grousers moves with the wheel (Wong & Reece 1967's effective radius r + h_g;
Bekker 1969's grouser analysis), so the wheel presses and shears the soil on the circle through
the grouser tips, and the trapped soil is carried backwards at the rim speed. Checks that do not
come from the code: a grousered wheel is then a smooth wheel of the tip radius wherever the
trapped soil is not carried faster than the ground (skid, the locked wheel: the measured CMU
wheels brake and sink alike there, -38.9 and -38.8 N, 49 and 50 mm locked); when driven, the
pocket layer of depth h_g, accelerated from the ground speed v to omega r_p (r_p its mean
radius), thins to h_g v / (omega r_p) by continuity, so the wheel digs in by h_g s_p with
s_p = 1 - v / (omega r_p); soil volume is conserved. With ``pocket_carry = "kept"`` the pockets
carry off only what they keep, h_g u_p f (no continuity floor): the wheel digs in by that over v
(mass balance), full pockets and smooth wheels are the same under both forms, and empty pockets
leave the smooth wheel of the tip radius.
"""

from __future__ import annotations

import numpy as np
import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_batch, simulate_swt
from scm_core.simulator.layout import P_MAXSINK, P_POCKET, P_SHEARSCALE, P_ZDATUM, pack

R, H_G, V = 0.058, 0.005, 0.01
GROUSERED = WheelGeometry(R=R, b=0.05, n_grousers=12, grouser_height=H_G)
TIP_RADIUS = WheelGeometry(R=R + H_G, b=0.05, n_grousers=0)
SMOOTH = WheelGeometry(R=R, b=0.05, n_grousers=0)
SOIL = SoilParams(k_phi=5e6, n=1.2, phi=30.0, J=0.012, shear_band=0.01)


def _rig(slip: float, contact: str = "tip_circle", carry: str = "continuity") -> RigConfig:
    return RigConfig(
        W=22.0,
        slip=slip,
        slip_convention="symmetric",
        carriage_speed=V,
        slip_radius=R,
        shear="displacement",
        drive_digging="mobilised",
        skid_ploughing="sliding_face",
        grouser_contact=contact,
        pocket_carry=carry,
    )


def test_tip_circle_packs_a_smooth_wheel_of_the_tip_radius_plus_the_pocket():
    """The kernel sees the rim at r + h_g, no grouser faces, the band below it as the dragged
    layer, and the pocket depth h_g; a smooth wheel is the same under both settings."""
    a = pack(SOIL, GROUSERED, _rig(0.5))
    b = pack(SOIL, TIP_RADIUS, _rig(0.5))
    assert a[P_POCKET] == H_G and b[P_POCKET] == 0.0
    differ = np.flatnonzero(a != b)
    assert set(differ) == {P_POCKET}
    smooth = WheelGeometry(R=R, b=0.05, n_grousers=0)
    np.testing.assert_array_equal(
        pack(SOIL, smooth, _rig(0.5)), pack(SOIL, smooth, _rig(0.5, "faces"))
    )


def test_a_skidding_grousered_wheel_is_a_smooth_wheel_of_its_tip_radius():
    """In skid and locked, the trapped soil is not carried faster than the ground: the same
    run as the smooth wheel of radius r + h_g, bit for bit."""
    slips = (-0.5, -1.0)
    grousered = simulate_batch([SOIL] * 2, GROUSERED, [_rig(s) for s in slips])
    smooth = simulate_batch([SOIL] * 2, TIP_RADIUS, [_rig(s) for s in slips])
    assert grousered.ok.all() and smooth.ok.all()
    np.testing.assert_array_equal(grousered.means, smooth.means)


def test_a_driven_grousered_wheel_digs_in_by_the_thinned_pocket_layer():
    """Driven, the pocket layer thins by continuity and the wheel sinks by h_g s_p more than
    the smooth wheel of the tip radius (s_p = 1 - v/(omega r_p), r_p = r + h_g/2), to within
    a quarter of it: the dug layer lowers the ground under the loaded nodes alike, so the
    wheel's bearing needs the same depth below the lowered ground (first order); the drawbar
    pull changes little (the band's shear is the same)."""
    slips = (0.25, 0.5, 0.9)
    grousered = simulate_batch([SOIL] * 3, GROUSERED, [_rig(s) for s in slips])
    smooth = simulate_batch([SOIL] * 3, TIP_RADIUS, [_rig(s) for s in slips])
    assert grousered.ok.all() and smooth.ok.all()
    dig = grousered.means[:, 2] - smooth.means[:, 2]
    omega = V / (R * (1.0 - np.array(slips)))  # lab slip = drive slip here
    s_p = 1.0 - V / (omega * (R + 0.5 * H_G))
    print("dig [mm]", 1e3 * dig, "expected", 1e3 * H_G * s_p)
    np.testing.assert_allclose(dig, H_G * s_p, rtol=0.25)


def test_fuller_pockets_dig_deeper_by_what_they_carry_off():
    """With pockets that leave the contact fuller than continuity fills them (``pocket_fill``
    f), the net excavation is h_g u_p (f + (1 - f) v / (omega r_p)) per width and time, and
    the wheel digs in by that over v (mass balance: the rut under the wheel is what was carried
    off per unit travel): at f = 1, h_g (omega r_p / v - 1), the pockets' spare capacity.
    Within a quarter, as above, at slips where the full pockets do not bottom the wheel out."""
    slips = (0.25, 0.5)
    fills = (0.0, 0.5, 1.0)
    soils = [SOIL.replace(pocket_fill=f) for f in fills for _ in slips]
    rigs = [_rig(s) for _ in fills for s in slips]
    grousered = simulate_batch(soils, GROUSERED, rigs)
    smooth = simulate_batch([SOIL] * 2, TIP_RADIUS, [_rig(s) for s in slips])
    assert grousered.ok.all() and smooth.ok.all()
    dig = grousered.means[:, 2].reshape(3, 2) - smooth.means[:, 2]
    omega = V / (R * (1.0 - np.array(slips)))
    speed = omega * (R + 0.5 * H_G)  # omega r_p
    expected = np.array([H_G * (speed - V) * (f + (1.0 - f) * V / speed) / V for f in fills])
    print("dig [mm]", 1e3 * dig, "expected", 1e3 * expected)
    assert np.all(np.diff(dig, axis=0) > 0)  # fuller pockets dig deeper
    np.testing.assert_allclose(dig, expected, rtol=0.25)


@pytest.mark.parametrize(("slip", "fill"), [(0.5, 0.0), (0.9, 0.0), (0.9, 0.5)])
def test_pocket_transport_conserves_volume(slip, fill):
    """The trapped soil moves from under the wheel to behind it: only compaction (and spill)
    removes volume."""
    d = simulate_swt(SOIL.replace(pocket_fill=fill), GROUSERED, _rig(slip)).diagnostics
    balance = d["volume_final"] - d["volume_initial"] + d["compacted_volume"] + d["volume_spilled"]
    assert abs(balance) / d["compacted_volume"] < 1e-9
    assert d["volume_spilled"] <= 1e-3 * d["compacted_volume"]


@pytest.mark.parametrize("contact", ["tip_circle", "rim_bearing", "faces"])
def test_a_rim_datum_reports_the_sinkage_a_grouser_height_less_and_nothing_else(contact: str):
    """``sinkage_datum = "rim"`` moves only the zero of z, from the tips' first contact to the
    rim's (radius R, measured to the grouser base): every sample of z is h_g less, to rounding,
    and the forces are the same bit for bit; a smooth wheel reports the same under both."""
    soil = [SOIL]
    outer = simulate_swt(SOIL, GROUSERED, _rig(0.5, contact))
    rim_rig = _rig(0.5, contact).model_copy(update={"sinkage_datum": "rim"})
    rim = simulate_swt(SOIL, GROUSERED, rim_rig)
    assert outer.ok and rim.ok
    np.testing.assert_allclose(rim.series["z"], outer.series["z"] - H_G, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rim.series["F"], outer.series["F"])
    smooth = WheelGeometry(R=R, b=0.05, n_grousers=0)
    a = simulate_batch(soil, smooth, [_rig(0.5, contact)])
    b = simulate_batch(soil, smooth, [rim_rig])
    np.testing.assert_array_equal(a.means, b.means)


def test_rim_bearing_packs_a_smooth_wheel_of_the_rim_radius_that_shears_at_the_tips():
    """Rim bearing: the kernel sees the smooth rim of radius R, the pocket of depth h_g, and
    a shearing surface (R + h_g) / R times farther out than its contact circle; besides, z is
    reported from the tips (the default datum) and bottoms out at the outer radius."""
    a = pack(SOIL, GROUSERED, _rig(0.5, "rim_bearing"))
    rim = WheelGeometry(R=R, b=0.05, n_grousers=0)
    b = pack(SOIL, rim, _rig(0.5, "rim_bearing"))
    assert a[P_POCKET] == H_G and a[P_SHEARSCALE] == (R + H_G) / R
    assert set(np.flatnonzero(a != b)) == {P_POCKET, P_SHEARSCALE, P_ZDATUM, P_MAXSINK}


def test_a_skidding_rim_bearing_wheel_is_the_smooth_rim_turning_at_its_tips_speed():
    """In skid the pockets carry nothing (slower than the ground), so the rim-bearing wheel at
    omega is the smooth wheel of radius R at omega (R + h_g) / R (the tips' speed at the rim):
    the same drawbar pull and sinkage, and the torque (R + h_g) / R times larger (the shear
    acts at the tips). Locked, it pulls and sinks as the smooth rim bit for bit."""
    kin = (R + H_G) / R
    rim = WheelGeometry(R=R, b=0.05, n_grousers=0)
    omega = 0.5 * V / (R + 0.5 * H_G) * 0.9  # pockets slower than the ground
    common = dict(
        W=22.0,
        carriage_speed=V,
        duration=12.0,
        dt=0.02,
        shear="displacement",
        drive_digging="mobilised",
        skid_ploughing="sliding_face",
        slip_convention="symmetric",
    )
    grousered = simulate_swt(
        SOIL, GROUSERED, RigConfig(omega=omega, grouser_contact="rim_bearing", **common)
    )
    smooth = simulate_swt(SOIL, rim, RigConfig(omega=omega * kin, **common))
    assert grousered.ok and smooth.ok
    np.testing.assert_allclose(grousered.series["F"], smooth.series["F"], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(grousered.series["z"], smooth.series["z"] + H_G, atol=1e-12)
    np.testing.assert_allclose(grousered.series["T"], kin * smooth.series["T"], rtol=1e-9)
    locked = [_rig(-1.0, "rim_bearing")]
    a = simulate_batch([SOIL], GROUSERED, locked)
    b = simulate_batch([SOIL], rim, locked)
    np.testing.assert_array_equal(a.means[:, 0], b.means[:, 0])
    np.testing.assert_allclose(a.means[:, 1], kin * b.means[:, 1], rtol=1e-12)
    np.testing.assert_allclose(a.means[:, 2], b.means[:, 2] + H_G, atol=1e-12)


@pytest.mark.parametrize("shear", ["velocity", "displacement"])
@pytest.mark.parametrize("slip", [0.5, 0.0, -0.5])
def test_rim_slip_shears_at_the_tips_with_the_rims_slip_scaled_by_the_shearing_radius(
    shear: str, slip: float
):
    """grouser_slip = 'rim' (Ding et al. 2011): the slip velocity of the shearing surface is
    (r + h_g) / r times the smooth rim's at the same rim slip, so eq. (8)'s mobilised shear,
    1 - exp(-|v_j| / J) or 1 - exp(-j / J), equals the smooth rim's with J r / (r + h_g).
    Without soil flow (which also moves the soil at those speeds) the rim-slip wheel pulls and
    sinks as that smooth rim, and its torque is (r + h_g) / r times larger (the shear acts at
    the tips). At zero rim slip the tips then pull no more than the rim does, where the tips'
    own velocity (grouser_slip = 'tips') slides the trapped soil at omega h_g."""
    kin = (R + H_G) / R
    rim = WheelGeometry(R=R, b=0.05, n_grousers=0)
    common = dict(
        W=22.0,
        slip=slip,
        slip_convention="symmetric",
        carriage_speed=V,
        slip_radius=R,
        duration=12.0,
        dt=0.02,
        shear=shear,
        bulldozing=False,
    )
    j_rim = SOIL.model_copy(update={"J": SOIL.J / kin})
    g = simulate_swt(
        SOIL, GROUSERED, RigConfig(grouser_contact="rim_bearing", grouser_slip="rim", **common)
    )
    s = simulate_swt(j_rim, rim, RigConfig(**common))
    assert g.ok and s.ok
    np.testing.assert_allclose(g.series["F"], s.series["F"], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(g.series["z"], s.series["z"] + H_G, atol=1e-12)
    np.testing.assert_allclose(g.series["T"], kin * s.series["T"], rtol=1e-9, atol=1e-12)
    if slip == 0.0:
        tips = simulate_swt(
            SOIL, GROUSERED, RigConfig(grouser_contact="rim_bearing", grouser_slip="tips", **common)
        )
        assert tips.means.F > g.means.F + 0.5  # the tips' slip pulls at zero rim slip


def test_grouser_slip_changes_only_a_rim_bearing_grousered_wheel():
    """'rim' packs the shearing radius ratio into the slip slot of a rim-bearing grousered
    wheel only: a smooth wheel, grouser faces and the tip circle are bit for bit as with
    'tips'."""
    from scm_core.simulator.layout import P_SLIPV

    smooth = WheelGeometry(R=R, b=0.05, n_grousers=0)
    for wheel, contact in (
        (smooth, "rim_bearing"),
        (GROUSERED, "faces"),
        (GROUSERED, "tip_circle"),
    ):
        rig = _rig(0.5, contact)
        a = pack(SOIL, wheel, rig)
        b = pack(SOIL, wheel, rig.model_copy(update={"grouser_slip": "rim"}))
        np.testing.assert_array_equal(a, b)
    a = pack(SOIL, GROUSERED, _rig(0.5, "rim_bearing"))
    b = pack(SOIL, GROUSERED, _rig(0.5, "rim_bearing").model_copy(update={"grouser_slip": "rim"}))
    assert set(np.flatnonzero(a != b)) == {P_SLIPV} and b[P_SLIPV] == (R + H_G) / R


@pytest.mark.parametrize(("slip", "expected"), [(-1.0, 0.0), (-0.5, 0.5), (0.0, 1.0), (0.5, 1.0)])
def test_rim_drive_scales_the_rims_slip_in_drive_and_keeps_it_in_skid(slip, expected):
    """'rim_drive': the carriage speed counts sv = 1 + (kin - 1) min(omega r / v, 1) times, so
    the tips' slip at the bottom, kin omega r - sv v, is kin times the rim's while driving (and
    zero at zero slip, as 'rim') and the rim's own omega r - v in skid (at lock -v)."""
    from scm_core.simulator.layout import P_OMEGA, P_SLIPV

    kin = (R + H_G) / R
    rig = _rig(slip, "rim_bearing").model_copy(update={"grouser_slip": "rim_drive"})
    p = pack(SOIL, GROUSERED, rig)
    assert p[P_SLIPV] == pytest.approx(1.0 + (kin - 1.0) * expected, rel=1e-12)
    rim_slip = p[P_OMEGA] * R - V
    tips_slip = kin * p[P_OMEGA] * R - p[P_SLIPV] * V
    assert tips_slip == pytest.approx(kin * rim_slip if slip >= 0 else rim_slip, abs=1e-15)


def test_a_locked_rim_drive_wheel_is_the_smooth_rim_but_for_its_torque():
    """A locked wheel translates at v whatever the radius of its shearing surface: with
    'rim_drive' the rim-bearing grousered wheel (trapped soil at phi, its sinkage read from the
    rim) brakes and sinks as the smooth rim of friction phi bit for bit, the whole model on
    (flows, erosion, sliding face), and its torque is r_s / r times the rim's."""
    kin = (R + H_G) / R
    locked = _rig(-1.0, "rim_bearing").model_copy(update={"steady_tolerance": None})
    g = simulate_swt(
        SOIL,
        GROUSERED,
        locked.model_copy(update={"grouser_slip": "rim_drive", "sinkage_datum": "rim"}),
    )
    s = simulate_swt(SOIL, WheelGeometry(R=R, b=0.05, n_grousers=0), locked)
    assert g.ok and s.ok
    np.testing.assert_array_equal(g.series["F"], s.series["F"])
    np.testing.assert_array_equal(g.series["z"], s.series["z"])
    np.testing.assert_allclose(g.series["T"], kin * s.series["T"], rtol=1e-9, atol=1e-12)
    ding = simulate_swt(
        SOIL, GROUSERED, locked.model_copy(update={"grouser_slip": "rim", "sinkage_datum": "rim"})
    )
    assert ding.means.F < s.means.F - 0.5  # 'rim' slides the locked tips at kin v


# ---- pocket_carry = "kept": the pockets carry off only what they keep (no continuity floor)


def test_a_smooth_wheel_and_full_pockets_are_the_same_under_both_forms():
    """No pockets, nothing to carry: a smooth wheel runs bit for bit the same; pockets that
    leave full (f = 1) carry h_g u_p under both forms."""
    slips = (-0.5, 0.0, 0.25, 0.5)  # full pockets bottom the wheel out by slip 0.9
    for wheel, soil in ((SMOOTH, SOIL), (GROUSERED, SOIL.replace(pocket_fill=1.0))):
        for contact in ("tip_circle", "rim_bearing"):
            kept = simulate_batch([soil] * 4, wheel, [_rig(s, contact, "kept") for s in slips])
            cont = simulate_batch([soil] * 4, wheel, [_rig(s, contact) for s in slips])
            assert kept.ok.all() and cont.ok.all()
            np.testing.assert_array_equal(kept.means, cont.means)


def test_pockets_that_keep_nothing_leave_the_smooth_wheel_of_the_tip_radius():
    """f = 0 with 'kept': the trapped soil is carried round and spilled back under the wheel,
    nothing is excavated, so the trapped-soil wheel is the smooth wheel of radius r + h_g bit
    for bit (driven as in skid), where continuity digs it in by h_g s_p."""
    slips = (0.25, 0.5, 0.9)
    grousered = simulate_batch([SOIL] * 3, GROUSERED, [_rig(s, carry="kept") for s in slips])
    smooth = simulate_batch([SOIL] * 3, TIP_RADIUS, [_rig(s) for s in slips])
    cont = simulate_batch([SOIL] * 3, GROUSERED, [_rig(s) for s in slips])
    assert grousered.ok.all() and smooth.ok.all() and cont.ok.all()
    np.testing.assert_array_equal(grousered.means, smooth.means)
    assert np.all(cont.means[:, 2] > grousered.means[:, 2] + 0.5 * H_G * 0.25)


def test_kept_pockets_dig_in_by_what_they_carry_off():
    """'kept', fill f: the net excavation is h_g u_p f per width and time, so the wheel digs in
    by h_g f u_p / v more than the smooth wheel of its tip radius (mass balance: the rut under
    the wheel is what was carried off per unit travel), u_p = omega r_p - v, r_p = r + h_g / 2.
    Within a quarter, as the continuity form's test (the dug layer lowers the loaded nodes
    alike; the bearing needs the same depth below it to first order), at slips and fills where
    the wheel does not bottom out; fuller pockets dig deeper."""
    slips = (0.5, 0.75)
    fills = (0.25, 0.5, 1.0)
    soils = [SOIL.replace(pocket_fill=f) for f in fills for _ in slips]
    rigs = [_rig(s, carry="kept") for _ in fills for s in slips]
    grousered = simulate_batch(soils, GROUSERED, rigs)
    smooth = simulate_batch([SOIL] * 2, TIP_RADIUS, [_rig(s) for s in slips])
    assert grousered.ok.all() and smooth.ok.all()
    dig = grousered.means[:, 2].reshape(3, 2) - smooth.means[:, 2]
    omega = V / (R * (1.0 - np.array(slips)))
    u_p = omega * (R + 0.5 * H_G) - V
    expected = np.array([H_G * f * u_p / V for f in fills])
    print("dig [mm]", 1e3 * dig, "expected", 1e3 * expected)
    assert np.all(np.diff(dig, axis=0) > 0)
    np.testing.assert_allclose(dig, expected, rtol=0.25)


@pytest.mark.parametrize(("slip", "fill"), [(0.5, 0.25), (0.9, 0.25)])
def test_kept_pocket_transport_conserves_volume(slip: float, fill: float) -> None:
    """The kept soil moves from under the wheel to behind it: only compaction (and spill)
    removes volume."""
    d = simulate_swt(
        SOIL.replace(pocket_fill=fill), GROUSERED, _rig(slip, carry="kept")
    ).diagnostics
    balance = d["volume_final"] - d["volume_initial"] + d["compacted_volume"] + d["volume_spilled"]
    assert abs(balance) / d["compacted_volume"] < 1e-9
    assert d["volume_spilled"] <= 1e-3 * d["compacted_volume"]
