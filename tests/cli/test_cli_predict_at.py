"""``scm-calib predict --at``: conditions nobody measured, on the calibrated wheel."""

from __future__ import annotations

from pathlib import Path

from scm_core.calibration import load_case
from scm_core.signals import load_dataset
from services.cli.predict import describe_wheel, parse_at, prediction_title, study_geometry


def test_predict_at_takes_the_study_wheel_unless_told_otherwise() -> None:
    """``predict --at``: the geometry every dataset of the study shares fills what the condition
    leaves out (a CMU smooth-wheel study predicts its own smooth wheel, not the paper's
    grousered default); a condition that names it wins."""
    summary = {
        "datasets": [
            {"conditions": {"W": 23.2, "R": 0.058, "b": 0.05, "n_grousers": 0}},
            {"conditions": {"W": 25.3, "R": 0.058, "b": 0.05, "n_grousers": 0}},
        ]
    }
    geometry = study_geometry(summary)
    assert geometry == {"R": 0.058, "b": 0.05, "n_grousers": 0}
    (own,) = parse_at(("W=24.6 N,slip=0.231,carriage_speed=10 mm/s",), geometry)
    assert own.conditions["n_grousers"] == 0 and own.conditions["R"] == 0.058
    assert own.conditions["W"] == 24.6 and own.conditions["slip"] == 0.231
    (other,) = parse_at(("W=25,slip=0.5,n_grousers=12,grouser_height=5 mm",), geometry)
    assert other.conditions["n_grousers"] == 12 and other.conditions["grouser_height"] == 0.005
    mixed = {"datasets": [{"conditions": {"R": 0.058}}, {"conditions": {"R": 0.1}}]}
    assert study_geometry(mixed) == {}


def test_a_cross_wheel_prediction_is_titled_by_the_wheel_it_predicts() -> None:
    """``predict --data``: the figure of a study's posterior on datasets of a wheel it never saw
    names that wheel (the cross-wheel check of docs/cmu-record.md); on its own wheel, or on a
    wheel among a joint study's, it keeps the plain title."""
    examples = Path(__file__).resolve().parents[2] / "examples"
    case = load_case(examples / "cmu_grouser.toml")
    smooth = [load_dataset(p) for p in sorted((examples / "cmu_smooth").glob("*.csv"))[:2]]
    grousered = [load_dataset(p) for p in sorted((examples / "cmu_grouser").glob("*.csv"))[:2]]

    def summary(data):
        return {"datasets": [{"conditions": d.conditions.to_sim_config()} for d in data]}

    assert prediction_title(case, summary(grousered), grousered, 200) == (
        "cmu_grouser: posterior predictions (200 draws)"
    )
    assert prediction_title(case, summary(grousered), smooth, 200) == (
        "cmu_grouser's posterior on another wheel (R 58 mm, b 50 mm, smooth), 200 draws"
    )
    assert prediction_title(case, summary(smooth + grousered), smooth, 200).endswith("(200 draws)")
    assert prediction_title(case, summary(smooth), grousered, 50).endswith(
        "(R 58 mm, b 50 mm, 12 grousers of 5 mm), 50 draws"
    )
    assert describe_wheel({"R": 0.125}) == "R 125 mm"
