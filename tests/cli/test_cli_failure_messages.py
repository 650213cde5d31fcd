"""Failed model runs said in words (issue 69: "2900 model runs (4 failed)" said nothing of why
or where to read more)."""

from __future__ import annotations

from pathlib import Path

from scm_core.calibration.failures import describe_failures, failure_counts, reasons_text
from services.cli.calibrate import _print_summary


def test_reasons_in_words_in_a_fixed_order() -> None:
    by = {"unstable": 1, "bottomed_out": 3}
    assert describe_failures(4, by) == "4 failed: 3 bottomed out, 1 unstable"
    assert describe_failures(0, {}) == ""
    # a model that gave no reason for some of its failures
    assert describe_failures(6, by) == "6 failed: 3 bottomed out, 1 unstable, 2 for no reason given"
    assert describe_failures(2, {}) == "2 failed"
    assert reasons_text(1, {"invalid_configuration": 1}) == "1 invalid configuration"
    # a screening's status codes (-1: the configuration could not be built)
    assert failure_counts([0, 1, 1, -1, 3]) == {
        "bottomed_out": 2,
        "invalid_configuration": 1,
        "unstable": 1,
    }


def _summary(failed: int, by: dict[str, int]) -> dict:
    return {
        "case": {"name": "quick"},
        "status": "completed",
        "n_stages": 6,
        "model_runs": 2900,
        "failed_runs": failed,
        "failed_by": by,
        "parameters": ["phi"],
        "posterior": {
            "mean": {"phi": 0.5},
            "sd": {"phi": 0.01},
            "credible_interval_95": {"phi": [0.48, 0.52]},
            "map": {"phi": 0.5},
        },
        "log_evidence": -4.1,
        "log_evidence_se": 0.2,
        "final_exponent": 1.0,
    }


def test_the_calibration_says_why_its_runs_failed_and_where_to_read_more(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    monkeypatch.setenv("COLUMNS", "500")  # rich folds long lines at the terminal's width
    _print_summary(_summary(4, {"bottomed_out": 3, "unstable": 1}), tmp_path)
    out = " ".join(capsys.readouterr().out.split())
    assert "4 of 2900 model runs failed (log L = -inf): 3 bottomed out, 1 unstable" in out
    assert 'docs/simulator.md, "Statuses"' in out and "summary.json" in out


def test_no_failure_no_line(tmp_path: Path, capsys) -> None:
    _print_summary(_summary(0, {}), tmp_path)
    assert "failed (log L" not in capsys.readouterr().out
