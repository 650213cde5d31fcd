"""Test conditions: aliases, units in keys and values, merging, simulator keys."""

import pytest

from scm_core.signals import LogFormatError, TestConditions, merge_metadata


def test_alias_normal_load_and_validation():
    c = TestConditions(normal_load=315, slip=0.2)
    assert c.W == 315.0
    assert TestConditions(W=315, slip=-1.0, slip_convention="drive").slip == -1.0
    with pytest.raises(ValueError, match="convention is not named"):
        TestConditions(W=315, slip=-1.0)
    with pytest.raises(ValueError):
        TestConditions(W=315, slip=1.0)
    with pytest.raises(ValueError):
        TestConditions(W=315, slip=0.2, R=0.0)
    with pytest.raises(ValueError):
        TestConditions(W=315, slip=0.2, unknown=1)
    with pytest.raises(ValueError):
        TestConditions(W=float("nan"), slip=0.2)


def test_metadata_keys_units_and_provenance():
    meta = merge_metadata(
        [
            (
                "file",
                {
                    "Normal Load": "0.315 kN",
                    "slip": "20 %",
                    "wheel_radius [mm]": "125",
                    "wheel-width": "0.112 m",
                    "omega": "6 rpm",
                    "h_g": "9 mm",
                    "Grousers": "12",
                    "Soil": "WF34",
                    "Operator": "A. Tester",
                },
            )
        ]
    )
    c = meta.conditions
    assert pytest.approx(315.0) == c.W
    assert c.slip == pytest.approx(0.2)
    assert pytest.approx(0.125) == c.R and c.b == pytest.approx(0.112)
    assert c.omega == pytest.approx(6 * 2 * 3.141592653589793 / 60)
    assert c.grouser_height == pytest.approx(0.009) and c.n_grousers == 12
    assert meta.provenance == {"soil": "WF34", "operator": "A. Tester"}


def test_nested_sidecar_and_later_provenance_wins():
    meta = merge_metadata(
        [
            ("file", {"slip": "0.2", "W": "315", "soil": "old"}),
            ("sidecar", {"conditions": {"slip": 0.2}, "provenance": {"soil": "WF34"}}),
        ]
    )
    assert meta.provenance == {"soil": "WF34"}
    with pytest.raises(LogFormatError, match=r"'W' conflicts: 315\.0 in the file, 300\.0 in the x"):
        merge_metadata([("file", {"slip": 0.2, "W": 315}), ("x", {"normal_load": 300})])


def test_sim_config_derives_omega_from_carriage_speed():
    c = TestConditions(W=315, slip=0.2, carriage_speed=0.01, R=0.125, n_grousers=12)
    cfg = c.to_sim_config()
    assert cfg["omega"] == pytest.approx(0.01 / (0.8 * 0.125))
    assert cfg == {"W": 315.0, "slip": 0.2, "omega": cfg["omega"], "R": 0.125, "n_grousers": 12}
    assert TestConditions(W=1, slip=0).to_sim_config() == {"W": 1.0, "slip": 0.0}


def test_bad_metadata_values():
    with pytest.raises(LogFormatError, match="metadata 'slip': expected a number, got True"):
        merge_metadata([("metadata", {"slip": True, "W": 1})])
    with pytest.raises(LogFormatError, match="not JSON-compatible"):
        merge_metadata([("metadata", {"slip": 0.1, "W": 1, "when": object()})])


def test_lab_convention_skid_converts_to_both_slips_and_speeds():
    """(v_rim - v)/max(v, v_rim) = -0.5 at v = 10 mm/s: the rim moves at 5 mm/s, and the drive
    convention 1 - v/(omega r) reads 1 - 10/5 = -1 (not -0.5: the two differ in skid)."""
    meta = merge_metadata(
        [
            (
                "file",
                {
                    "slip": "-0.5",
                    "slip_convention": "symmetric",
                    "carriage_speed": "10 mm/s",
                    "wheel_radius": "58 mm",
                    "normal_load": "23 N",
                },
            )
        ]
    )
    c = meta.conditions
    assert c.slip_symmetric == pytest.approx(-0.5) and c.slip == pytest.approx(-1.0)
    assert c.rim_speed == pytest.approx(0.005) and c.carriage_speed == pytest.approx(0.01)
    assert c.omega == pytest.approx(0.005 / 0.058)
    # the same test stated as two speeds, or as the drive-convention slip, is the same record
    assert TestConditions(W=23, carriage_speed=0.01, rim_speed=0.005, R=0.058) == c
    assert (
        TestConditions(W=23, slip=-1.0, slip_convention="drive", carriage_speed=0.01, R=0.058) == c
    )
    assert c.to_sim_config() == {
        "W": 23.0,
        "slip": -0.5,
        "slip_convention": "symmetric",
        "omega": c.omega,
        "R": 0.058,
    }


def test_unnamed_negative_slip_is_refused_naming_both_conventions():
    with pytest.raises(LogFormatError) as err:
        merge_metadata([("file", {"slip": "-0.5", "normal_load": "23 N"})])
    msg = str(err.value)
    assert "slip -0.5 is negative" in msg
    assert "'drive' (s = 1 - v/(omega r))" in msg and "'symmetric'" in msg


def test_locked_wheel_conditions():
    c = TestConditions(W=19.5, omega=0.0, carriage_speed=0.01, R=0.058)
    assert c.locked and c.slip is None and c.slip_symmetric == -1.0 and c.rim_speed == 0.0
    assert TestConditions.model_validate(c.model_dump()) == c  # the record round-trips
    cfg = c.to_sim_config()
    assert cfg["slip"] == -1.0 and cfg["slip_convention"] == "symmetric"
    assert cfg["carriage_speed"] == 0.01


def test_inconsistent_kinematics_are_refused():
    with pytest.raises(ValueError, match="disagrees"):
        TestConditions(W=1, slip=0.2, carriage_speed=0.01, rim_speed=0.02)
    with pytest.raises(ValueError, match="unknown slip convention"):
        TestConditions(W=1, slip=0.2, slip_convention="wong")


@pytest.mark.parametrize(
    ("raw", "deg"),
    [
        ({"slip_angle": "30"}, 30.0),  # a bare number is in degrees
        ({"slip angle [deg]": "60"}, 60.0),
        ({"beta": "-45 deg"}, -45.0),
        ({"steering_angle": "0.5 rad"}, 0.5 * 180.0 / 3.141592653589793),
        ({"slip_angle_deg": "90"}, 90.0),
    ],
)
def test_slip_angle_aliases_and_units(raw, deg):
    """A lab's slip angle (issue 70), in degrees whatever unit it came in; the simulator gets
    it as RigConfig.slip_angle."""
    meta = merge_metadata([("file", {"W": "20 N", "slip": "0.2", **raw})])
    assert meta.conditions.slip_angle == pytest.approx(deg, rel=1e-12)
    assert meta.conditions.to_sim_config()["slip_angle"] == pytest.approx(deg, rel=1e-12)


def test_no_slip_angle_is_straight_and_leaves_the_simulator_keys_as_they_were():
    c = TestConditions(W=20, slip=0.2)
    assert c.slip_angle is None and "slip_angle" not in c.to_sim_config()


@pytest.mark.parametrize("bad", ["91", "-120 deg", "2 rad"])
def test_a_slip_angle_beyond_90_deg_is_refused_naming_it(bad):
    with pytest.raises(
        LogFormatError,
        match=r"slip_angle = .*(less than or equal to 90|greater than or equal to -90)",
    ):
        merge_metadata([("file", {"W": "20 N", "slip": "0.2", "slip_angle": bad})])
