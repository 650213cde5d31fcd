"""Unit conversion of columns and metadata to SI."""

import math

import numpy as np
import pytest

from scm_core.signals import LogFormatError, load_log, write_log
from scm_core.signals.units import parse_value, unit_factor

META = {"slip": 0.2, "W": 315.0, "R": 0.125, "b": 0.112, "n_grousers": 12}


def si_series():
    t = np.arange(0, 50, 0.01)
    F = 20 + np.sin(t)
    T = 5 + 0.1 * np.cos(t)
    z = 0.012 + 0.001 * np.sin(0.5 * t)
    return t, F, T, z


def test_handwritten_mm_kn_ms_log_equals_si(tmp_path):
    t, F, T, z = si_series()
    si = load_log(write_log(tmp_path / "si.csv", t, F, T, z, META, sidecar=False))
    lines = [
        "# slip: 20 %",
        "# normal_load: 0.315 kN",
        "# wheel_radius: 125 mm",
        "# wheel width [cm]: 11.2",
        "# grousers: 12",
        "t [ms],F [kN],T [N*mm],z [mm]",
    ]
    lines += [
        f"{a * 1e3!r},{b / 1e3!r},{c * 1e3!r},{d * 1e3!r}"
        for a, b, c, d in zip(t.tolist(), F.tolist(), T.tolist(), z.tolist(), strict=True)
    ]
    path = tmp_path / "mm.csv"
    path.write_text("\n".join(lines) + "\n")
    other = load_log(path)
    for key in ("drawbar_pull", "torque", "sinkage"):
        np.testing.assert_allclose(other.series.raw[key], si.series.raw[key], rtol=1e-12)
    np.testing.assert_allclose(other.series.t, si.series.t, rtol=1e-12, atol=1e-15)
    for key in ("F", "T", "z"):
        assert other.responses[key].mean == pytest.approx(si.responses[key].mean, rel=1e-9)
    c, d = other.conditions, si.conditions
    assert (c.slip, c.W, c.R, c.b, c.n_grousers) == pytest.approx((d.slip, d.W, d.R, d.b, 12))


def test_writer_units_read_back_as_si(tmp_path):
    t, F, T, z = si_series()
    units = {"time": "ms", "drawbar_pull": "kN", "torque": "kNm", "sinkage": "mm"}
    path = write_log(tmp_path / "u.csv", t, F, T, z, META, units=units)
    assert "time [ms],drawbar_pull [kN],torque [kNm],sinkage [mm]" in path.read_text()
    ds = load_log(path)
    np.testing.assert_allclose(ds.series.raw["sinkage"], z, rtol=1e-12)
    np.testing.assert_allclose(ds.series.raw["drawbar_pull"], F, rtol=1e-12)
    np.testing.assert_allclose(ds.series.t, t, rtol=1e-12, atol=1e-15)


def test_optional_columns_and_percent_slip(tmp_path):
    t, F, T, z = si_series()
    path = tmp_path / "opt.csv"
    rows = [
        f"{a!r},{b!r},{c!r},{d!r},{0.0703},{20.0}"
        for a, b, c, d in zip(*(x.tolist() for x in (t, F, T, z)), strict=True)
    ]
    text = "# slip: 0.2\n# W: 315\ntime [s],F [N],M [Nm],z [m],Fz [lbf],slip [%]\n"
    path.write_text(text + "\n".join(rows) + "\n")
    ds = load_log(path)
    np.testing.assert_allclose(ds.series.raw["normal_force"], 0.0703 * 4.4482216152605)
    np.testing.assert_allclose(ds.series.raw["slip"], 0.2)
    assert set(ds.series.filtered) == {"drawbar_pull", "torque", "sinkage", "normal_force", "slip"}


@pytest.mark.parametrize(
    ("quantity", "unit", "factor"),
    [
        ("time", "min", 60.0),
        ("time", "ms", 1e-3),
        ("force", "lbf", 4.4482216152605),
        ("torque", "N.m", 1.0),
        ("torque", "N m", 1.0),
        ("torque", "N\u00b7m", 1.0),
        ("torque", "NM", 1.0),
        ("torque", "Nmm", 1e-3),
        ("torque", "lbf*ft", 1.3558179483314004),
        ("length", "in", 0.0254),
        ("length", "cm", 0.01),
        ("slip", "%", 0.01),
        ("slip", "-", 1.0),
        ("angular_velocity", "rpm", 2 * math.pi / 60),
        ("speed", "mm/s", 1e-3),
    ],
)
def test_unit_factors(quantity, unit, factor):
    assert unit_factor(quantity, unit, "x") == pytest.approx(factor, rel=1e-15)


def test_parse_value():
    assert parse_value("125 mm", "length", "R") == pytest.approx(0.125)
    assert parse_value("125mm", "length", "R") == pytest.approx(0.125)
    assert parse_value("0.125", "length", "R") == 0.125
    assert parse_value("12.5", "length", "R", default_unit="cm") == pytest.approx(0.125)
    assert parse_value("-1e1 %", "slip", "s") == pytest.approx(-0.1)
    with pytest.raises(LogFormatError, match="R: unknown length unit 'parsec'"):
        parse_value("3 parsec", "length", "R")
    with pytest.raises(LogFormatError, match="not a number"):
        parse_value("nan", "length", "R")
