"""Sweeps and force maps of `scm-calib predict`: a slip sweep's load follows the datasets'
measured loads; a slip-angle sweep and a map keep the template's."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from scm_core.calibration.model import DatasetTerms
from scm_core.calibration.predict import map_targets, sweep_loads, sweep_targets
from scm_core.signals import load_dataset

ROOT = Path(__file__).resolve().parents[2]
CMU = ROOT / "examples" / "cmu_smooth"


def _terms(stem: str) -> DatasetTerms:
    d = load_dataset(CMU / f"{stem}.csv")
    return DatasetTerms(d.name, d.conditions.to_sim_config(), (math.nan,) * 3)


def test_sweep_load_interpolates_between_the_datasets_and_holds_beyond() -> None:
    locked, skid, drive = (
        _terms(s) for s in ("cmu_smooth_sm100", "cmu_smooth_sm050", "cmu_smooth_sp090")
    )
    w = {n: t.conditions["W"] for n, t in zip("lsd", (locked, skid, drive), strict=True)}
    loads = sweep_loads([drive, locked, skid])  # any order
    assert loads is not None
    targets = sweep_targets(skid, [-1.0, -0.75, 0.2, 0.95], loads)
    got = [t.conditions["W"] for t in targets]
    s_skid = -0.500144  # the dataset's symmetric slip
    f = (-0.75 + 1.0) / (s_skid + 1.0)
    assert got[0] == pytest.approx(w["l"])
    assert got[1] == pytest.approx(w["l"] + f * (w["s"] - w["l"]), rel=1e-4)
    g = (0.2 - s_skid) / (0.899741 - s_skid)
    assert got[2] == pytest.approx(w["s"] + g * (w["d"] - w["s"]), rel=1e-4)
    assert got[3] == pytest.approx(w["d"])  # beyond the last dataset: its load
    assert all(t.conditions["slip_convention"] == "symmetric" for t in targets)


def test_sweep_keeps_the_template_load_with_one_dataset() -> None:
    skid = _terms("cmu_smooth_sm050")
    assert sweep_loads([skid]) is None
    targets = sweep_targets(skid, [-0.2, 0.5], sweep_loads([skid]))
    assert {t.conditions["W"] for t in targets} == {skid.conditions["W"]}


def test_a_slip_angle_sweep_keeps_the_rest_of_the_template() -> None:
    """``key="slip_angle"``: each point is the template's conditions with the slip angle [deg]
    set, its slip (convention and wheel speed as given), load and wheel kept; the loads of
    several datasets apply along the slip only."""
    skid = _terms("cmu_smooth_sm050")
    loads = sweep_loads([_terms("cmu_smooth_sm100"), skid, _terms("cmu_smooth_sp090")])
    targets = sweep_targets(skid, [-30.0, 0.0, 45.0], loads, key="slip_angle")
    assert [t.name for t in targets] == ["slip_angle -30", "slip_angle 0", "slip_angle 45"]
    for t, beta in zip(targets, (-30.0, 0.0, 45.0), strict=True):
        assert t.conditions == {**skid.conditions, "slip_angle": beta}
        assert all(math.isnan(m) for m in t.means)
    with pytest.raises(ValueError, match="slip or slip_angle"):
        sweep_targets(skid, [300.0], key="W")


def test_a_map_grid_is_the_slip_sweep_at_every_slip_angle() -> None:
    """``map_targets``: slip-major, each point the slip sweep's conditions at that slip (the
    template's carriage speed, symmetric convention, the template's load) with the slip angle
    set; a steered template's own angle is replaced."""
    skid = _terms("cmu_smooth_sm050")
    steered = DatasetTerms(skid.name, {**skid.conditions, "slip_angle": 10.0}, skid.means)
    grid = map_targets(steered, [-0.5, 0.5], [0.0, 30.0, 60.0])
    assert [t.name for t in grid[:2]] == ["slip -0.5, slip_angle 0", "slip -0.5, slip_angle 30"]
    swept = sweep_targets(skid, [-0.5, 0.5])
    expected = [(s, a) for s in swept for a in (0.0, 30.0, 60.0)]
    assert len(grid) == len(expected) == 6
    for t, (s, a) in zip(grid, expected, strict=True):
        assert t.conditions == {**s.conditions, "slip_angle": a}
        assert t.conditions["W"] == skid.conditions["W"]
