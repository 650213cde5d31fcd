"""The README's first command and the commands it says to run next, verbatim and in order, on a
fresh results folder (issue 69): each exits 0 and leaves the outputs the README names; the
quick case's four runs converge (issue 44's acceptance: R-hat <= 1.01 for every parameter)."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from scm_core.calibration import preset_cost

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")
CLI = ".venv/bin/scm-calib"

pytestmark = pytest.mark.slow


def _block_after(marker: str) -> list[str]:
    """The lines of the first ```bash block after ``marker``."""
    rest = README[README.index(marker) :]
    block = re.search(r"```bash\n(.*?)```", rest, re.S)
    assert block, f"no bash block after {marker!r}"
    return [line for line in block.group(1).splitlines() if line.strip()]


def readme_commands() -> list[list[str]]:
    """The README's first scm-calib command (the end of the fresh-machine line) and the walk
    after it, as argument lists for this interpreter."""
    first = _block_after("## On a fresh machine")[0].split(" && ")[-1]
    lines = [first, *_block_after("<!-- readme-walk -->")]
    assert all(line.startswith(CLI + " ") for line in lines), lines
    return [[sys.executable, "-m", "services.cli", *shlex.split(line)[1:]] for line in lines]


def named_outputs() -> list[str]:
    """The paths under quick_results/ that the README's "What came out" section names."""
    section = README[README.index("### What came out") : README.index("## What is here")]
    return sorted(set(re.findall(r"`(quick_results/[\w./]+)`", section)))


def test_the_readme_walk_runs_in_order_on_a_fresh_folder(tmp_path: Path) -> None:
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    outputs = []
    for cmd in readme_commands():
        proc = subprocess.run(
            cmd, cwd=tmp_path, capture_output=True, text=True, timeout=1200, env=env
        )
        assert proc.returncode == 0, (cmd, proc.stderr[-2000:])
        assert "Traceback" not in proc.stderr and "Warning" not in proc.stderr, proc.stderr
        outputs.append(proc.stdout)
    out = tmp_path / "quick_results"
    doc = json.loads((out / "runs.json").read_text())
    rhat = {name: p["rhat"] for name, p in doc["parameters"].items()}
    assert all(r <= 1.01 for r in rhat.values()), rhat
    assert doc["converged"] and "converged: R-hat <= 1.01" in outputs[0]
    for name in rhat:
        assert name in outputs[0]  # the agreement table is printed
    assert "converged: R-hat <= 1.01" in outputs[1]  # diagnose on the group
    named = named_outputs()
    assert {"quick_results/predictions/", "quick_results/inference_data.nc"} <= set(named)
    for path in named:
        assert (tmp_path / path).exists(), path
    for name in ("runs.json", "posterior_pooled.csv", "chrono_soil.cpp", "chrono_soil.py"):
        assert (out / name).is_file(), name
    expected = preset_cost("quick").model_runs  # what the dashboard shows beside the preset
    for k in range(1, 5):
        summary = json.loads((out / f"run_{k}" / "summary.json").read_text())
        assert abs(summary["model_runs"] - expected) <= 0.25 * expected, summary["model_runs"]
        assert (out / f"run_{k}" / "figures" / "fit_map.png").is_file()
    pred = json.loads((out / "predictions" / "predictions.json").read_text())
    assert pred["study"]["runs"] == 4 and pred["draws"] == 200
    (target,) = pred["datasets"]
    assert target["name"] == "wf34_s050"
    # the calibration's own log: its measured means inside the pooled posterior's 95 % bands
    assert all(r["inside_predictive"] for r in target["responses"].values()), target
