"""``scm-calib predict --sweep slip_angle=...`` and ``--map``: their ranges and grids (the runs
and the force map's files: tests/calibration/test_calib_cli.py)."""

from __future__ import annotations

import pytest

from services.cli.common import CLIError
from services.cli.force_map import MAX_POINTS, parse_map
from services.cli.predict import parse_sweep


def test_a_sweep_varies_the_slip_or_the_slip_angle_by_a_labs_names() -> None:
    """``--sweep``: the symmetric slip or the slip angle [deg], under any name a lab file's
    metadata gives either (case, spaces and hyphens as the metadata parser reads them)."""
    assert parse_sweep(None) is None
    assert parse_sweep("slip=-0.5:0.6:3") == ("slip", pytest.approx([-0.5, 0.05, 0.6]))
    assert parse_sweep("slip_lab=0:0.5:2") == ("slip", [0.0, 0.5])
    assert parse_sweep("slip_angle=-90:90:5") == ("slip_angle", [-90.0, -45.0, 0.0, 45.0, 90.0])
    for alias in ("beta", "Steering-Angle", "yaw angle", "slip_angle_deg"):
        assert parse_sweep(f"{alias}=0:30:2") == ("slip_angle", [0.0, 30.0])


@pytest.mark.parametrize(
    ("spec", "needle"),
    [
        ("slip_angle=-91:0:3", "slip_angle needs -90 <= LO < HI <= 90 (deg)"),
        ("beta=0:90.5:2", "slip_angle needs -90 <= LO < HI <= 90 (deg)"),
        ("slip_angle=30:0:3", "slip_angle needs -90 <= LO < HI <= 90 (deg)"),
        ("slip_angle=0:90:1", "2 <= N <= 200"),
        ("slip_angle=nan:90:3", "slip_angle needs"),
        ("slip=-1:1:3", "slip needs -1 <= LO < HI < 1"),
        ("slip_angle=a:b:3", "LO and HI must be numbers"),
        ("slip_angle=0:90", "expected slip=LO:HI:N or slip_angle=LO:HI:N"),
        ("W=100:300:3", "expected slip=LO:HI:N or slip_angle=LO:HI:N"),
    ],
)
def test_a_bad_sweep_is_one_line_naming_the_option(spec: str, needle: str) -> None:
    with pytest.raises(CLIError) as err:
        parse_sweep(spec)
    message = err.value.message
    assert message.startswith(f"--sweep {spec!r}: ") and needle in message
    assert "\n" not in message


def test_a_map_grid_defaults_each_axis_it_leaves_out() -> None:
    """``--map`` bare: slips -0.9..0.9 by 0.1 and slip angles 0..90 deg by 15 (133 points);
    an axis given replaces its default only."""
    slips, angles = parse_map("")
    assert slips == pytest.approx([round(-0.9 + 0.1 * k, 10) for k in range(19)])
    assert angles == [0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0]
    assert parse_map(None) is None
    slips2, angles2 = parse_map("beta=-45:45:3")
    assert slips2 == slips and angles2 == [-45.0, 0.0, 45.0]
    assert parse_map(" slip=0:0.5:2 , slip_angle=0:90:2") == ([0.0, 0.5], [0.0, 90.0])


@pytest.mark.parametrize(
    ("spec", "needle"),
    [
        ("slip=-0.9:0.9:20,slip_angle=0:90:11", f"220 points, over the limit of {MAX_POINTS}"),
        ("slip=-0.9:0.9:200", "200 slips x 7 slip angles = 1400 points"),
        ("slip=0:0.5:2,slip_ratio=0:0.2:2", "slip is given twice"),
        ("slip=0:0.5:2,slip_angle=-100:0:3", "slip_angle needs -90 <= LO < HI <= 90 (deg)"),
        ("slip", "expected slip=LO:HI:N or slip_angle=LO:HI:N"),
    ],
)
def test_a_bad_map_is_one_line_naming_the_option(spec: str, needle: str) -> None:
    """Refused before anything runs: the whole spec named after ``--map``."""
    with pytest.raises(CLIError) as err:
        parse_map(spec)
    message = err.value.message
    assert message.startswith(f"--map {spec!r}: ") and needle in message
    assert "\n" not in message
