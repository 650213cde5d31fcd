"""The quick case's verdict over four runs (issue 44's acceptance): the paper's leader form is
caught stopping at different places along the k_phi-n ridge (that the study default converges
is checked by the README walk, tests/calibration/test_calib_readme_walk.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.slow


def _runs(tmp_path: Path, *extra: str) -> tuple[subprocess.CompletedProcess, dict]:
    out = tmp_path / "runs"
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "calibrate", str(ROOT / "examples" / "quick.toml"),
         "--runs", "4", "--workers", "2", "--no-plots", "--quiet", "--out", str(out), *extra],
        capture_output=True, text=True, timeout=1200,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return proc, json.loads((out / "runs.json").read_text())


def test_the_leader_form_is_caught_on_the_ridge(tmp_path: Path) -> None:
    proc, doc = _runs(tmp_path, "--moves", "leader")
    rhat = {name: p["rhat"] for name, p in doc["parameters"].items()}
    assert rhat["k_phi"] > 1.05 and rhat["n"] > 1.05, rhat
    assert not doc["converged"] and {"k_phi", "n"} <= set(doc["disagreeing"])
    warning = [line for line in proc.stderr.splitlines() if line.startswith("warning:")]
    assert warning and "k_phi" in warning[-1] and "n" in warning[-1]
