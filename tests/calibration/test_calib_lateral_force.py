"""The lateral force Fy as a calibration response (issue 70): a case lists ``responses = ["F",
"Fy", "z"]`` with ``sigma_Fy``; a dataset that did not measure Fy (NaN, as the CMU data's
torque) has no Fy term; a steered wheel simulated at a known soil, written as a lab summary
with its lateral force, is calibrated back to that soil."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from scm_core.calibration import CaseDefinition, CaseError, StudyModel, run_tmcmc
from scm_core.signals import load_summary
from scm_core.signals.responses import N_RESPONSES, RESPONSE_KEYS
from scm_core.simulator import RigConfig, SoilParams, simulate_swt

#: coarse, short runs of the paper's wheel (the truth is simulated with the same numerics)
SIM = {"duration": 8.0, "dt": 0.04, "dx": 0.01, "offset_F": 4.0, "offset_T": 4.0, "offset_z": 4.0}
NOMINAL = {"bulk_density": 1330.0, "sigma_F": 5.0, "sigma_T": 2.0, "sigma_z": 0.005}
PHI_TRUE = 30.0


def _case(responses: list[str], **sampler) -> CaseDefinition:
    return CaseDefinition.from_dict(
        {
            "name": "steered",
            "seed": 7,
            "likelihood": "gaussian",
            "responses": responses,
            "parameters": {
                "phi": {"dist": "uniform", "lower": 22.0, "upper": 38.0},
                "sigma_Fy": {"dist": "uniform", "lower": 0.2, "upper": 6.0},
            },
            "nominal": NOMINAL,
            "simulator": SIM,
            "sampler": {"n_samples": 40, "n_steps": 2, **sampler},
        }
    )


def test_a_case_names_fy_and_its_sigma() -> None:
    case = _case(["F", "Fy", "z"])
    assert case.responses == ("F", "Fy", "z") and case.sigma_spec()["Fy"] == ("parameter", 1)
    # the default stays the straight wheel's responses: no sigma_Fy is asked of older cases
    doc = case.to_dict()
    del doc["responses"]
    assert CaseDefinition.from_dict(doc).responses == ("F", "T", "z")
    doc["responses"] = ["F", "Fy"]
    doc["parameters"] = {"phi": doc["parameters"]["phi"]}
    with pytest.raises(CaseError, match=r"sigma_Fy: response Fy is used but sigma_Fy"):
        CaseDefinition.from_dict(doc)


def _summary(beta: float | None, means: dict[str, float]) -> bytes:
    """A lab summary (one row per response) of a steered wheel's steady means."""
    lines = [f"# slip_angle: {beta} deg"] if beta is not None else []
    lines += ["# normal_load: 315 N", "# slip: 0.2", "# wheel_radius: 0.125 m", "# n_trials: 1"]
    lines.append("response,mean,sd,unit")
    units = {"F": "N", "lateral_force": "N", "z": "mm"}
    scale = {"F": 1.0, "lateral_force": 1.0, "z": 1000.0}
    for key, value in means.items():
        lines.append(f"{key},{value * scale[key]:.10g},0.5,{units[key]}")
    return ("\n".join(lines) + "\n").encode()


def test_a_dataset_without_fy_has_no_fy_term() -> None:
    """The likelihood of a study fitting F, Fy and z on a straight dataset (no Fy measured)
    is that of F and z alone: sigma_Fy does not enter it."""
    straight = load_summary(_summary(None, {"F": 60.0, "z": 0.02}), name="straight")
    steered = load_summary(
        _summary(30.0, {"F": 55.0, "lateral_force": 40.0, "z": 0.025}), name="steered"
    )
    model = StudyModel(_case(["F", "Fy", "z"]), [straight, steered])
    assert model.datasets[0].measured == ("F", "z") and model.datasets[1].steered
    means = np.zeros((3, 2, N_RESPONSES))
    means[:, :, RESPONSE_KEYS.index("F")] = [[58.0, 57.0], [61.0, 50.0], [60.0, 55.0]]
    means[:, :, RESPONSE_KEYS.index("z")] = 0.021
    means[:, :, RESPONSE_KEYS.index("Fy")] = [[0.0, 38.0], [0.0, 45.0], [0.0, 40.0]]
    sigma_fy = np.array([0.5, 2.0, 4.0])
    sigma = np.column_stack([np.full(3, 5.0), sigma_fy, np.full(3, 0.005)])
    got = model.log_likelihood_from_means(means, sigma, [0])
    expect = stats.norm.logpdf(60.0, means[:, 0, 0], 5.0) + stats.norm.logpdf(0.02, 0.021, 0.005)
    np.testing.assert_allclose(got, expect, rtol=1e-12)
    got = model.log_likelihood_from_means(means, sigma, [1])
    expect = (
        stats.norm.logpdf(55.0, means[:, 1, 0], 5.0)
        + stats.norm.logpdf(40.0, means[:, 1, 3], sigma_fy)
        + stats.norm.logpdf(0.025, 0.021, 0.005)
    )
    np.testing.assert_allclose(got, expect, rtol=1e-12)


def test_a_steered_wheel_is_calibrated_back_to_its_soil() -> None:
    """Truth: the paper's wheel at slip 0.2 and 45 deg on a soil of phi = 30 deg. Its steady
    F, Fy and z, written as a lab summary with ``lateral_force [N]``, are fitted with phi and
    sigma_Fy free: the posterior of phi covers 30 deg, and Fy is what pins it (the lateral
    force at 45 deg grows with tan phi)."""
    soil = SoilParams(phi=PHI_TRUE, bulk_density=NOMINAL["bulk_density"])
    rig = RigConfig(W=315.0, slip=0.2, slip_angle=45.0, **SIM)
    truth = simulate_swt(soil, rig=rig)
    assert truth.ok and truth.means.Fy > 10.0
    data = load_summary(
        _summary(45.0, {"F": truth.means.F, "lateral_force": truth.means.Fy, "z": truth.means.z}),
        name="steered 45",
    )
    assert data.means["Fy"] == pytest.approx(truth.means.Fy, rel=1e-9)
    case = _case(["F", "Fy", "z"], max_stages=12)
    model = StudyModel(case, [data])
    result = run_tmcmc(model, case.prior(), 40, case.seed, case.tmcmc_settings())
    assert result.status == "completed"
    phi = result.samples[:, 0]
    lo, hi = np.quantile(phi, [0.025, 0.975])
    assert lo <= PHI_TRUE <= hi, (lo, hi)
    assert hi - lo < 8.0  # informative: the prior is 16 deg wide
    # the simulated responses returned with the likelihood carry Fy (the 4th per dataset)
    assert result.final.responses.shape == (40, N_RESPONSES)
    assert np.all(result.final.responses[:, RESPONSE_KEYS.index("Fy")] > 0.0)
    assert math.isfinite(result.log_evidence)


def test_predictions_and_screenings_give_fy_where_it_is_not_zero_by_symmetry() -> None:
    """A straight wheel's lateral force is zero: predictions and Morris screenings of straight
    data report F, T and z as they always did; a steered condition, a case fitting Fy or a
    measured Fy adds it."""
    from scm_core.calibration import MorrisSettings, analyze_sensitivity, sensitivity_design
    from scm_core.calibration.model import DatasetTerms
    from scm_core.calibration.predict import predicted_keys

    straight = DatasetTerms("s", {"W": 315.0, "slip": 0.2}, (1.0, 2.0, 0.01))
    steered = DatasetTerms("b", {"W": 315.0, "slip": 0.2, "slip_angle": 30.0}, (np.nan,) * 3)
    measured = DatasetTerms("m", {"W": 315.0, "slip": 0.2}, (1.0, np.nan, 0.01, 0.5))
    fz = _case(["F", "Fy", "z"])
    phi_only = {"phi": fz.to_dict()["parameters"]["phi"]}
    ftz = fz.with_changes(responses=["F", "T", "z"], parameters=phi_only)
    assert predicted_keys(ftz, [straight]) == ("F", "T", "z")
    assert predicted_keys(ftz, [straight, steered]) == RESPONSE_KEYS
    assert predicted_keys(ftz, [measured]) == RESPONSE_KEYS
    assert predicted_keys(fz, [straight]) == RESPONSE_KEYS
    design = sensitivity_design(ftz, MorrisSettings(r=2, levels=4, seed=1))
    Y = np.random.default_rng(0).normal(size=(design.n_points, N_RESPONSES))
    assert list(analyze_sensitivity(design, Y).to_dict()["responses"]) == ["F", "T", "z"]
    doc = analyze_sensitivity(design, Y, keys=RESPONSE_KEYS).to_dict()
    assert doc["responses"] == {"F": "N", "T": "N m", "z": "m", "Fy": "N"}
    assert set(doc["mu_star"]) == set(RESPONSE_KEYS)
