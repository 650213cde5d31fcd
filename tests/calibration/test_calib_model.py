"""StudyModel: the batch likelihood against a hand computation of eq. (12)-(15) and (6) from
``simulate_batch`` means; failed and invalid runs; responses; configuration precedence."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from scm_core.calibration import CaseDefinition, DatasetTerms, StudyModel, build_configs
from scm_core.inference import TMCMCSettings, evaluate_points, run_tmcmc
from scm_core.inference.early_rejection import is_parted
from scm_core.signals.responses import N_RESPONSES, RESPONSE_KEYS
from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_batch

SIM = {"duration": 12.0, "dx": 0.01, "dt": 0.04, "offset_F": 6.0, "offset_T": 6.0, "offset_z": 6.0}

DATASETS = (
    DatasetTerms(
        "s02",
        {
            "W": 315.0,
            "slip": 0.2,
            "omega": 0.1,
            "R": 0.125,
            "b": 0.112,
            "n_grousers": 12,
            "grouser_height": 0.009,
        },
        (52.0, 10.1, 0.0192),
    ),
    DatasetTerms("s05", {"W": 300.0, "slip": 0.5, "R": 0.125}, (120.0, 15.5, 0.0231)),
)

#        k_phi  n    phi   R      sigma_F
POINTS = np.array(
    [
        [1.0e7, 1.10, 27.0, 0.125, 3.0],
        [2.0e6, 1.30, 30.0, 0.130, 4.0],
        [1.0e3, 2.00, 27.0, 0.125, 3.0],  # far too soft: bottoms out
        [1.0e7, 1.10, 27.0, 0.015, 3.0],  # grousers higher than half the rim: invalid
    ]
)


def make_case(likelihood: str) -> CaseDefinition:
    return CaseDefinition.from_dict(
        {
            "name": "model test",
            "likelihood": likelihood,
            "parameters": {
                "k_phi": {"dist": "log_uniform", "lower": 1e3, "upper": 1e8},
                "n": {"dist": "uniform", "lower": 0.8, "upper": 2.0},
                "phi": {"dist": "uniform", "lower": 11.5, "upper": 37.3},
                "R": {"dist": "uniform", "lower": 0.01, "upper": 0.2},
                "sigma_F": {"dist": "uniform", "lower": 0.0, "upper": 5.0},
            },
            "nominal": {"J": 0.004, "sigma_T": 0.4, "sigma_z": 0.0008},
            "simulator": SIM,
        }
    )


@pytest.fixture(scope="module")
def hand_means() -> np.ndarray:
    """Means (2 valid points, 2 datasets, N_RESPONSES) from simulate_batch with configs built
    by hand."""
    soils, wheels, rigs = [], [], []
    for k_phi, n, phi, R, _ in POINTS[:2]:
        for d in DATASETS:
            c = d.conditions
            soils.append(SoilParams(k_phi=k_phi, n=n, phi=phi, J=0.004))
            wheels.append(WheelGeometry(R=R))  # calibrated R is the rim radius ...
            rigs.append(  # ... while the lab's R stays the slip radius
                RigConfig(W=c["W"], slip=c["slip"], omega=0.1, slip_radius=0.125, **SIM)
            )
    res = simulate_batch(soils, wheels, rigs)
    assert res.ok.all()
    return res.means.reshape(2, 2, N_RESPONSES)


@pytest.mark.parametrize("likelihood", ["normalized", "gaussian"])
def test_likelihood_equals_hand_computation(likelihood: str, hand_means: np.ndarray) -> None:
    model = StudyModel(make_case(likelihood), DATASETS)
    ll, resp, _, _ = model.log_likelihood_batch(POINTS)
    assert resp.shape == (4, 2 * N_RESPONSES)
    np.testing.assert_array_equal(resp[:2], hand_means.reshape(2, 2 * N_RESPONSES))
    for i in range(2):
        sigma = np.array([POINTS[i, 4], 0.4, 0.0008])
        expected = 0.0
        for k, d in enumerate(DATASETS):
            # the case's responses: F, T, z (eq. (14)-(15))
            xi = (np.array(d.means[:3]) - hand_means[i, k, :3]) / sigma
            terms = -0.5 * xi**2 - 0.5 * math.log(2 * math.pi)  # eq. (13)
            if likelihood == "gaussian":
                terms = terms - np.log(sigma)  # eq. (6): the 1/sigma factor
            expected += float(terms.sum())  # eq. (12), times the datasets
        assert ll[i] == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert np.all(np.isneginf(ll[2:])) and np.all(np.isnan(resp[2:]))


def test_failed_and_invalid_runs_count_as_failed() -> None:
    model = StudyModel(make_case("normalized"), DATASETS)
    _, ok = model.simulate_means(POINTS)
    assert ok[:2].all() and not ok[2:].any()
    ev = evaluate_points(POINTS, model.log_likelihood_batch)
    assert ev.failed_runs == 2
    assert np.isfinite(ev.log_likelihood[:2]).all() and np.isneginf(ev.log_likelihood[2:]).all()
    assert ev.responses is not None and ev.responses.shape == (4, 2 * N_RESPONSES)
    assert model.response_names == tuple(f"{r}[{d}]" for d in ("s02", "s05") for r in RESPONSE_KEYS)


def test_rows_do_not_depend_on_batch_and_model_pickles() -> None:
    model = StudyModel(make_case("gaussian"), DATASETS)
    ll, resp, _, _ = model.log_likelihood_batch(POINTS)
    for i in range(POINTS.shape[0]):
        ll_i, resp_i, _, _ = model.log_likelihood_batch(POINTS[i : i + 1])
        np.testing.assert_array_equal(ll_i, ll[i : i + 1])
        np.testing.assert_array_equal(resp_i, resp[i : i + 1])
    clone = pickle.loads(pickle.dumps(model))
    ll2, resp2, _, _ = clone.log_likelihood_batch(POINTS[:2])
    np.testing.assert_array_equal(ll2, ll[:2])
    np.testing.assert_array_equal(resp2, resp[:2])


def test_simulate_at_gives_the_series() -> None:
    model = StudyModel(make_case("normalized"), DATASETS)
    res = model.simulate_at(POINTS[0], 1)
    assert res.ok and res.series["t"][-1] == pytest.approx(SIM["duration"])
    means, _ = model.simulate_means(POINTS[:1])
    assert (res.means.F, res.means.T, res.means.z, res.means.Fy) == pytest.approx(
        tuple(means[0, 1])
    )
    same = model.simulate_at(POINTS[0], DATASETS[1])  # any dataset, not only the model's
    np.testing.assert_array_equal(same.series["F"], res.series["F"])


def test_configuration_precedence() -> None:
    nominal = {"J": 0.002, "R": 0.13, "W": 100.0, "K": 4e7}
    simulator = {"dx": 0.01, "W": 200.0}
    # the dataset's conditions override nominal and simulator values; the lab R is the slip
    # radius and the rim radius unless R is calibrated
    soil, wheel, rig = build_configs(nominal, simulator, {"W": 315.0, "R": 0.125}, {"phi": 25})
    assert (soil.J, soil.K, soil.phi) == (0.002, 4e7, 25.0)
    assert (wheel.R, rig.slip_radius, rig.W, rig.dx) == (0.125, 0.125, 315.0, 0.01)
    _, wheel, rig = build_configs(nominal, simulator, {"W": 315.0, "R": 0.125}, {"R": 0.14})
    assert (wheel.R, rig.slip_radius) == (0.14, 0.125)
    # without a dataset R, the slip radius is the nominal rim radius
    _, wheel, rig = build_configs(nominal, {}, {"W": 315.0, "slip": 0.2}, {})
    assert (wheel.R, rig.slip_radius, rig.W) == (0.13, 0.13, 315.0)


@pytest.mark.parametrize("likelihood", ["normalized", "gaussian"])
def test_datasets_as_parts_assemble_the_batch_likelihood_bit_for_bit(likelihood: str) -> None:
    """Early rejection (issue 12) runs a study's datasets one at a time: each dataset's means do
    not depend on the others, its term never exceeds its bound (zero residuals), and the
    assembled output is the batch likelihood's, bit for bit (invalid points included)."""
    model = StudyModel(make_case(likelihood), DATASETS)
    assert is_parted(model) and sorted(model.part_order) == [0, 1]
    assert model.part_in_base == (False, False)
    ll, resp, base, failure = model.log_likelihood_batch(POINTS)
    assert base is None
    parts = [model.run_part(POINTS, k) for k in range(2)]
    ll2, resp2 = model.assemble(POINTS, [r for _, r, _ in parts])
    np.testing.assert_array_equal(ll2, ll)
    np.testing.assert_array_equal(resp2, resp)
    for k, (term, means, why) in enumerate(parts):
        np.testing.assert_array_equal(means, resp[:, N_RESPONSES * k : N_RESPONSES * (k + 1)])
        ok = np.isfinite(term)
        assert ok[:2].all() and not ok[2:].any()
        assert np.all(term[ok] <= model.part_bound(POINTS, k)[ok])
        # why each run failed, in the simulator's words (issue 69): the soft soil's wheel
        # sinks past max_sinkage, the grousers higher than half the rim are refused unbuilt
        assert why.tolist() == ["", "", "bottomed_out", "invalid_configuration"]
    assert failure.tolist() == ["", "", "bottomed_out", "invalid_configuration"]
    np.testing.assert_allclose(parts[0][0][:2] + parts[1][0][:2], ll[:2], rtol=1e-14)


def test_early_rejection_on_a_study_gives_the_same_samples_with_fewer_runs() -> None:
    """A short TMCMC run of a two-dataset study with and without early rejection."""
    case = make_case("gaussian")
    model = StudyModel(case, DATASETS)
    prior = case.prior()
    runs = {}
    for er in (False, True):
        settings = TMCMCSettings(n_steps=4, max_stages=3, early_rejection=er)
        runs[er] = run_tmcmc(model, prior, 40, 5, settings)
    off, on = runs[False], runs[True]
    for a, b in zip(off.stages, on.stages, strict=True):
        np.testing.assert_array_equal(a.samples, b.samples)
        np.testing.assert_array_equal(a.log_likelihood, b.log_likelihood)
        np.testing.assert_array_equal(a.responses, b.responses)
        assert a.log_evidence == b.log_evidence
        assert b.part_runs + b.part_runs_saved == a.part_runs
    assert sum(s.early_rejections for s in on.stages) > 0
