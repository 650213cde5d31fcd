"""Synthetic lab logs: seeded, noisy, ramped, readable by the lab-log loader with the truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from scm_core.calibration import NoiseModel, SyntheticError, synthesize_log
from scm_core.signals import load_log, write_log
from scm_core.simulator import RigConfig, SoilParams, WheelGeometry

RIG = RigConfig(slip=0.3, dx=0.01, dt=0.04, duration=12.0, offset_F=6, offset_T=6, offset_z=6)
SOIL = SoilParams(phi=27.0, J=0.004)


@pytest.fixture(scope="module")
def log():
    return synthesize_log(SOIL, WheelGeometry(), RIG, duration=30.0, ramp_s=3.0, seed=4)


def test_seeded_and_shaped(log) -> None:
    again = synthesize_log(SOIL, WheelGeometry(), RIG, duration=30.0, ramp_s=3.0, seed=4)
    other = synthesize_log(SOIL, WheelGeometry(), RIG, duration=30.0, ramp_s=3.0, seed=5)
    np.testing.assert_array_equal(log.F, again.F)
    assert not np.array_equal(log.F, other.F)
    assert log.t.size == 30 * 50 + 1 and log.t[0] == 0.0 and log.rate_hz == pytest.approx(50.0)
    assert log.metadata["R"] == WheelGeometry().R and log.metadata["slip"] == 0.3
    assert log.metadata["true_parameters"]["phi"] == 27.0
    # the ramp: drawbar pull and torque start from zero (plus noise)
    assert abs(log.F[:5].mean()) < 6.0 and abs(log.T[:5].mean()) < 0.6
    # noise: the noisy log differs from the clean resampled signal by about the set levels
    clean = synthesize_log(
        SOIL,
        WheelGeometry(),
        RIG,
        duration=30.0,
        ramp_s=3.0,
        seed=4,
        noise=NoiseModel(scale=0.0),
    )
    resid = log.F - clean.F
    assert 1.5 < resid.std() < 3.0
    assert np.all(clean.slip == 0.3)


def test_written_log_reads_back_with_truth(log, tmp_path) -> None:
    path = write_log(
        tmp_path / "syn.csv",
        log.t,
        log.F,
        log.T,
        log.z,
        log.metadata,
        normal_force=log.normal_force,
        slip=log.slip,
        precision=7,
    )
    ds = load_log(path, offset=10.0)
    assert ds.conditions.slip == 0.3 and ds.conditions.W == 315.0 and ds.conditions.R == 0.125
    assert ds.provenance["true_parameters"]["phi"] == 27.0
    side = json.loads(path.with_suffix(".json").read_text())
    assert side["true_parameters"]["J"] == 0.004
    # the steady means are those of the clean simulation over the same window, within noise
    sim = log.simulation.series
    win = sim["t"] >= 10.0
    assert ds.means["F"] == pytest.approx(sim["F"][win].mean(), abs=3.0)
    assert ds.means["T"] == pytest.approx(sim["T"][win].mean(), abs=0.3)
    assert ds.means["z"] == pytest.approx(sim["z"][win].mean(), abs=3e-4)
    assert path.stat().st_size < 100_000


def test_failed_simulation_is_reported() -> None:
    with pytest.raises(SyntheticError, match="bottomed_out"):
        synthesize_log(SoilParams(k_phi=1e3, n=2.0), WheelGeometry(), RIG, duration=10.0)
    with pytest.raises(ValueError, match="duration"):
        synthesize_log(SOIL, WheelGeometry(), RIG, duration=-1.0)
