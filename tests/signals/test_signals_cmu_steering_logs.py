"""The CMU steering runs as lab files (``examples/cmu_steering/*/logs``, made by
``examples/cmu_steering/make_lab_files.py`` from ``runs.csv``): every condition of
``by_condition.csv`` has its log, which reads with its slip angle and the trials' means of F,
Fy and z that the authors' pooled table gives."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import pytest

from scm_core.signals import load_dataset

KIT = Path(__file__).resolve().parents[2] / "examples" / "cmu_steering"


def _table(wheel: str) -> list[dict[str, float]]:
    with open(KIT / wheel / "by_condition.csv", newline="") as fh:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(fh)]


@pytest.mark.parametrize("wheel", ["smooth", "grouser"])
def test_every_condition_has_its_log_with_the_tables_means(wheel: str) -> None:
    rows = _table(wheel)
    logs = sorted((KIT / wheel / "logs").glob("*.csv"))
    assert len(logs) == len(rows) == {"smooth": 36, "grouser": 20}[wheel]
    for row in rows:
        name = f"cmu_{wheel}_b{row['slip_angle_deg']:02.0f}_v{row['vry_cmd_mmps']:03.0f}"
        d = load_dataset(KIT / wheel / "logs" / f"{name}.csv")
        assert d.conditions.slip_angle == row["slip_angle_deg"]
        assert d.conditions.to_sim_config()["n_grousers"] == (12 if wheel == "grouser" else 0)
        # the authors' pooled means are the trials' means (printed to 6 digits in runs.csv)
        for key, column in (("F", "drawbar_pull_N"), ("Fy", "lateral_force_N"), ("z", "sinkage_m")):
            assert d.responses[key].mean == pytest.approx(row[f"{column}_mean"], rel=1e-4, abs=1e-5)
        assert d.conditions.to_sim_config()["W"] == pytest.approx(
            row["normal_load_N_mean"], rel=1e-4
        )
        cfg = d.conditions.to_sim_config()
        assert cfg["slip"] == pytest.approx(
            row["slip_lab_mean"], abs=1e-4
        )  # symmetric = drive, s >= 0


def test_the_logs_are_what_the_script_writes(tmp_path: Path) -> None:
    """The committed logs are the script's output from runs.csv, byte for byte."""
    spec = importlib.util.spec_from_file_location("make_lab_files", KIT / "make_lab_files.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for wheel in ("smooth", "grouser"):
        with open(KIT / wheel / "runs.csv", newline="") as fh:
            runs = module._conditions(list(csv.DictReader(fh)))
        for (angle, rim), trials in runs.items():
            text = module.lab_file(wheel, angle, rim, trials)
            name = text.splitlines()[0].removeprefix("# name: ")
            assert (KIT / wheel / "logs" / f"{name}.csv").read_text(encoding="utf-8") == text
