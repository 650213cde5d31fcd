"""``scm-calib predict --at``: conditions nobody measured, on the calibrated wheel."""

from __future__ import annotations

from services.cli.predict import parse_at, study_geometry


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
