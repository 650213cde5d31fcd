"""Figures and exports that iterate over the responses (issue 70's lateral force Fy): a
straight wheel's figures stay as they were, with no empty Fy panel; a steered wheel's, or data
that measured Fy, get one; results stored before Fy (three responses) draw as before."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from scm_core.calibration.predict import Band, ConditionPrediction, ResponsePrediction
from scm_core.signals import load_dataset, load_summary
from scm_core.signals.responses import RESPONSE_KEYS
from scm_core.simulator import RigConfig, simulate_swt
from services.exports.inference_data import RunPopulation, StageRow, inference_data
from services.plots.fit import fit_chart
from services.plots.predict import predictions_chart
from services.plots.sensitivity import stored_indices_figure
from services.plots.swt import swt_figure

LOG = Path(__file__).resolve().parents[2] / "examples" / "wf34_s020.csv"
FAST = {"duration": 6.0, "dt": 0.04, "dx": 0.01, "offset_F": 3.0, "offset_T": 3.0, "offset_z": 3.0}


def _labels(chart) -> list[str]:
    return [p.y.label for p in chart.panels if p is not None]


def test_a_straight_runs_figure_has_its_three_panels_a_steered_ones_four() -> None:
    straight = swt_figure(simulate_swt(rig=RigConfig(**FAST)))
    assert len(straight.axes) == 3 and tuple(straight.get_size_inches()) == (8.0, 7.5)
    steered = swt_figure(simulate_swt(rig=RigConfig(slip_angle=30.0, **FAST)))
    assert [ax.get_ylabel() for ax in steered.axes][-1] == "lateral force Fy [N]"
    assert len(steered.axes) == 4


def test_the_fit_draws_fy_only_where_a_dataset_measured_it() -> None:
    log = load_dataset(LOG)
    sim = simulate_swt(rig=RigConfig(**FAST))
    labels = _labels(fit_chart([log], [sim], responses=RESPONSE_KEYS))
    assert labels == ["drawbar pull F [N]", "torque T [N m]", "sinkage z [mm]"]
    steered = load_summary(
        b"# slip_angle: 30\n# W: 315 N\n# slip: 0.2\n# n_trials: 2\n"
        b"response,mean,sd,unit\nF,50,1,N\nFy,20,1,N\nz,20,1,mm\n",
        name="steered",
    )
    sim30 = simulate_swt(rig=RigConfig(slip_angle=30.0, **FAST))
    labels = _labels(fit_chart([steered], [sim30], responses=("F", "Fy", "z")))
    assert labels == ["drawbar pull F [N]", "sinkage z [mm]", "lateral force Fy [N]"]


def _prediction(keys: tuple[str, ...]) -> ConditionPrediction:
    band = Band(1.0, 0.5, 1.5)
    responses = {k: ResponsePrediction(k, band, band, None) for k in keys}
    return ConditionPrediction("a", {}, 0.2, 10, 0, responses, "predicted")


def test_predictions_without_fy_draw_no_fy_panel() -> None:
    chart = predictions_chart([_prediction(("F", "T", "z"))], [], responses=RESPONSE_KEYS)
    assert len(chart.panels) == 3 and "lateral force Fy [N]" not in _labels(chart)
    chart = predictions_chart([_prediction(RESPONSE_KEYS)], [], responses=RESPONSE_KEYS)
    assert _labels(chart)[-1] == "lateral force Fy [N]"


def _morris_doc(keys: tuple[str, ...]) -> dict:
    table = {r: {"phi": 0.5, "n": 0.5} for r in keys}
    return {
        "factors": [{"name": "phi"}, {"name": "n"}],
        "responses": dict.fromkeys(keys, "N"),
        "linear_index": table,
        "nonlinear_index": table,
        "r": 2,
        "levels": 4,
        "n_runs": 6,
        "n_failed_runs": 0,
    }


def test_morris_indices_have_a_panel_per_response_screened() -> None:
    assert len(stored_indices_figure(_morris_doc(("F", "T", "z")), "old").axes) == 3
    assert len(stored_indices_figure(_morris_doc(RESPONSE_KEYS), "steered").axes) == 4


def test_the_arviz_export_observes_fy_only_where_measured() -> None:
    run = RunPopulation(
        np.zeros((4, 1)), np.zeros(4), np.zeros(4), np.zeros((4, 1)), [StageRow(1.0, 0.3, -2.0)]
    )
    straight = {"a": {"means": {"F": 1.0, "z": 0.01}, "standard_errors": {"F": 0.1}}}
    idata = inference_data(["phi"], [run], observed=straight)
    assert set(idata.observed_data.data_vars) == {"F", "F_se", "T", "T_se", "z", "z_se"}
    steered = {"b": {"means": {"F": 1.0, "Fy": 20.0}, "standard_errors": {"Fy": 0.5}}}
    idata = inference_data(["phi"], [run], observed={**straight, **steered})
    assert float(idata.observed_data["Fy"][1]) == 20.0 and np.isnan(idata.observed_data["Fy"][0])
    assert idata.observed_data["Fy"].attrs["units"] == "N"
    json.dumps(idata.observed_data.attrs)  # plain attributes
