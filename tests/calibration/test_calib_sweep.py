"""Slip sweeps of `scm-calib predict`: the load follows the datasets' measured loads."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from scm_core.calibration.model import DatasetTerms
from scm_core.calibration.predict import sweep_loads, sweep_targets
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
