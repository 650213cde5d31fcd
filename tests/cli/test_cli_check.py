"""``scm-calib check``: what a study would read from lab files, and what is probably wrong."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from services.cli.check import check

ROOT = Path(__file__).resolve().parents[2]
LOG = ROOT / "examples" / "wf34_s020.csv"  # a 180 s time series, F T z, W 315 N, R 0.125 m
CMU = ROOT / "examples" / "cmu_smooth"


def _run(*args: str | Path):
    return CliRunner().invoke(check, [str(a) for a in args])


def _json(*args: str | Path) -> dict:
    res = _run("--json", *args)
    return json.loads(res.output), res.exit_code


def test_good_files_report_conditions_both_slips_and_windows() -> None:
    doc, code = _json(LOG, CMU / "cmu_smooth_sm100.csv", CMU / "cmu_smooth_sp050.csv")
    assert code == 0 and doc["errors"] == []
    log, locked, driven = doc["datasets"]
    assert log["kind"] == "timeseries" and log["window_s"][1] > log["window_s"][0]
    assert log["conditions"]["slip_drive"] == 0.2 and log["conditions"]["rim_speed_m_s"] > 0
    assert set(log["responses"]) == {"F", "T", "z"}
    # a locked wheel: symmetric slip -1, no drive slip, rim speed 0
    assert locked["conditions"]["slip_symmetric"] == -1.0
    assert locked["conditions"]["slip_drive"] is None
    assert locked["conditions"]["rim_speed_m_s"] == 0.0
    assert driven["kind"] == "summary" and driven["n_trials"] == 3
    # the CMU summaries have no torque, the log has: said once, naming the files
    (warning,) = doc["warnings"]
    assert "torque (T)" in warning and "wf34_s020.csv" in warning and "cmu_smooth_sm100" in warning
    table = _run(LOG, CMU / "cmu_smooth_sm100.csv")
    assert table.exit_code == 0 and "locked" in table.output and "[mm/s]" in table.output


def test_a_log_without_its_time_column_is_named(tmp_path: Path) -> None:
    """Without the time column the log reads as a summary of one trial per row: warned, with
    the fix."""
    lines = LOG.read_text().splitlines()
    body = [ln for ln in lines if ln.startswith("#")]
    rows = [ln.split(",", 1)[1] for ln in lines if not ln.startswith("#")]
    bad = tmp_path / "no_time.csv"
    bad.write_text("\n".join(body + rows) + "\n")
    doc, code = _json(bad)
    assert code == 0 and doc["datasets"][0]["kind"] == "summary"
    (warning,) = doc["warnings"]
    assert "no_time.csv" in warning and "time [s]" in warning


def test_a_unit_error_is_caught_by_magnitude(tmp_path: Path) -> None:
    """kN under a drawbar header in N: |F| = 48 kN against W = 315 N (10 W = 3.15 kN)."""
    text = LOG.read_text().replace("drawbar_pull [N]", "drawbar_pull [kN]")
    bad = tmp_path / "kn.csv"
    bad.write_text(text)
    doc, code = _json(bad)
    assert code == 0
    (warning,) = doc["warnings"]
    assert "kn.csv" in warning and "drawbar pull" in warning and "unit" in warning


def test_a_file_that_does_not_load_fails_with_its_name(tmp_path: Path) -> None:
    broken = tmp_path / "broken.csv"
    broken.write_text("# W: 315 N\ntime [s],drawbar_pull [N]\n0,abc\n")
    res = _run(LOG, broken)
    assert res.exit_code == 1
    assert "broken.csv" in res.output and "error:" in res.output
    assert "Traceback" not in res.output


def test_what_is_not_a_lab_file_is_said_in_words(tmp_path: Path) -> None:
    """Issue 69: a file whose header row is missing, a case file and a missing file each get
    one line saying what they are (not "no response", a field count, or Python's Errno)."""
    numbers = tmp_path / "noheader.csv"
    numbers.write_text("# W: 315\n0,1,2,3\n1,1,2,3\n")
    doc, code = _json(numbers, ROOT / "examples" / "quick.toml", tmp_path / "missing.csv")
    assert code == 1 and doc["datasets"] == []
    header, case, missing = doc["errors"]
    assert header.startswith("noheader.csv: line 2: no header row: the first row after the")
    assert "(0,1,2,3)" in header and "time [s],F [N]" in header
    assert header.count("\n") == 0
    assert case.startswith("quick.toml: a case file (TOML), not a lab file")
    assert "scm-calib calibrate" in case
    assert missing == f"{tmp_path / 'missing.csv'}: no such file or directory"
    assert not any("Errno" in e or "fields, but" in e or "no response" in e for e in doc["errors"])
    res = _run(numbers)
    assert res.exit_code == 1 and "Traceback" not in res.output
