"""The CMU grousered wheel's tests as the project reads them (issue 47's development data).

The expected values are the data README's own statements (shared/data/cmu_grouser_wheel/README.md,
"What the data show"), not numbers from our code: a converter or loader error shows here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from scm_core.calibration import load_case
from scm_core.signals import load_dataset
from scm_core.simulator import RigConfig

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _by_slip() -> dict[float, object]:
    out = {}
    for p in sorted((EXAMPLES / "cmu_grouser").glob("*.csv")):
        ds = load_dataset(p)
        out[round(ds.conditions.slip_symmetric, 1)] = ds
    return out


def test_five_slips_of_a_grousered_wheel_with_three_trials_each() -> None:
    data = _by_slip()
    assert sorted(data) == [-1.0, -0.5, 0.0, 0.5, 0.9]
    for ds in data.values():
        c = ds.conditions
        assert (c.R, c.b, c.n_grousers, c.grouser_height) == (0.058, 0.05, 12, 0.005)
        assert ds.n_trials == 3
        assert 19.0 <= c.W <= 27.0  # "the measured normal force of each run (19-27 N)"
        assert c.carriage_speed == pytest.approx(0.010, rel=0.002)  # 10 mm/s


def test_the_means_are_the_readmes() -> None:
    """README: 2.8 N at slip 0.5, 4.8 N at 0.9; sinkage 16 mm at 0, 25 at 0.5, 42 at 0.9;
    -17.7 N in skid (-0.5) and -38.9 N locked."""
    data = _by_slip()
    f = {s: ds.responses["F"].mean for s, ds in data.items()}
    z = {s: ds.responses["z"].mean * 1000 for s, ds in data.items()}
    assert f[0.5] == pytest.approx(2.8, abs=0.05) and f[0.9] == pytest.approx(4.8, abs=0.05)
    assert f[-0.5] == pytest.approx(-17.7, abs=0.05) and f[-1.0] == pytest.approx(-38.9, abs=0.05)
    assert z[0.0] == pytest.approx(16, abs=0.5) and z[0.5] == pytest.approx(25, abs=0.5)
    assert z[0.9] == pytest.approx(42, abs=0.5)


def test_the_single_wheel_cases_read_the_same_five_lab_slips() -> None:
    """cmu_smooth.toml and cmu_grouser.toml calibrate on the same five lab slips (the grousered
    wheel's: locked to 0.9), with the same model, priors and sampler; the grousered case adds
    the one parameter only a grousered wheel identifies, its pockets' fill, and one it cannot
    identify but a prediction of a smooth wheel from it needs, the smooth rim's friction on the
    soil (its prior the literature's)."""
    case = load_case(EXAMPLES / "cmu_grouser.toml")
    smooth = load_case(EXAMPLES / "cmu_smooth.toml")
    for c in (case, smooth):
        slips = [round(load_dataset(p).conditions.slip_symmetric, 1) for p in c.data_paths()]
        assert slips == [-1.0, -0.5, 0.0, 0.5, 0.9]
    extra = set(case.parameter_names) - set(smooth.parameter_names)
    assert extra == {"pocket_fill", "interface_friction"}
    assert set(smooth.parameter_names) <= set(case.parameter_names)
    for name in smooth.parameter_names:
        assert case.parameters[name] == smooth.parameters[name], name
    assert case.simulator == smooth.simulator and case.sampler == smooth.sampler


def test_the_joint_case_reads_both_wheels_with_one_soil() -> None:
    """cmu_joint.toml: the smooth wheel's nine slips and the grousered wheel's five; the wheels
    differ only by what each dataset's header says (geometry, load, speeds): no wheel key in the
    case itself, one set of soil parameters and one sinkage datum."""
    case = load_case(EXAMPLES / "cmu_joint.toml")
    smooth = load_case(EXAMPLES / "cmu_smooth.toml")
    data = [load_dataset(p) for p in case.data_paths()]
    grousered = [d for d in data if d.conditions.n_grousers]
    assert len(data) == 14 and len(grousered) == 5
    assert {(d.conditions.n_grousers, d.conditions.grouser_height) for d in grousered} == {
        (12, 0.005)
    }
    wheel_keys = {"R", "b", "n_grousers", "grouser_height", "grouser_thickness"}
    assert not wheel_keys & (set(case.nominal) | set(case.simulator) | set(case.parameters))
    # the smooth case's parameters and the grousered wheel's extensions: the rim's friction and
    # the pockets' fill (docs/simulator.md step 1), both soil-side (no wheel dimension)
    extra = set(case.parameter_names) - set(smooth.parameter_names)
    assert set(smooth.parameter_names) <= set(case.parameter_names)
    assert "interface_friction" in extra and extra <= {"interface_friction", "pocket_fill"}
    # the smooth case's model but for how a locked grousered wheel's tips slide, which a smooth
    # wheel ignores bit for bit (test_grouser_slip_changes_only_a_rim_bearing_grousered_wheel)
    joint_rig = RigConfig.model_validate(case.simulator)
    assert joint_rig == RigConfig.model_validate({**smooth.simulator, "grouser_slip": "rim_drive"})
    assert case.nominal == {**smooth.nominal, "bulk_density": 1330.0}  # the data README's


def test_the_grousered_wheel_does_not_see_the_rims_friction() -> None:
    """Its trapped soil shears soil on soil (at phi): the grousered case's runs are the same bit
    for bit at either end of interface_friction's prior and with or without the stuck soil's
    rule (locked and at slip 0.5), so its posterior of it is its prior (what a prediction of a
    smooth wheel from this soil carries), whatever its tests say."""
    from scm_core.calibration import StudyModel
    from services.studies.kinds.checks import prior_medians

    case = load_case(EXAMPLES / "cmu_grouser.toml")
    smooth = EXAMPLES / "cmu_smooth" / "cmu_smooth_sp050.csv"
    model = StudyModel(case, [load_dataset(case.data_paths()[3]), load_dataset(smooth)])
    k = case.parameter_names.index("interface_friction")
    runs = []
    for value in (0.5, 1.0):
        theta = prior_medians(case)
        theta[k] = value
        runs.append([model.simulate_at(theta, d) for d in (0, 1)])
    for key in ("F", "T", "z"):
        assert np.array_equal(runs[0][0].series[key], runs[1][0].series[key]), key
    # the smooth rim at slip 0.5 shears on its surface: half the friction, a weaker wheel
    assert runs[0][1].means.F < runs[1][1].means.F - 1.0
    # nor where a smooth rim's soil would stick (stuck_shear): bit for bit either way
    sliding = case.with_changes(simulator={**case.simulator, "stuck_shear": "interface"})
    locked_and_driven = [load_dataset(case.data_paths()[j]) for j in (0, 3)]
    here = StudyModel(case, locked_and_driven)
    other = StudyModel(sliding, locked_and_driven)
    theta = prior_medians(case)
    theta[k] = 0.5
    for d in (0, 1):
        a, b = here.simulate_at(theta, d), other.simulate_at(theta, d)
        assert np.array_equal(a.series["F"], b.series["F"]), d
        assert np.array_equal(a.series["z"], b.series["z"]), d
