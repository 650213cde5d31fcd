"""What a study of each preset costs: the numbers behind the dashboard's cost beside a preset
(``scm_core.calibration.presets``: stages after the prior's, share of the planned runs made,
seconds per simulation).

Runs ``scm-calib calibrate`` on each preset's example case (``examples/quick.toml``,
``examples/case1.toml`` ...; the simulator compiled beforehand) and prints per run the samples,
stages, model runs against the sampler's plan, the share of a later stage's planned runs that
were made, wall seconds per simulation, and the cost the presets table predicts beside what was
measured.

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_presets.py [--presets quick 1] [--samples 500]
        [--workers 2] [--repeats 1]

``--samples`` sets the paper cases' samples per stage (their own 2000 take 5-10 min each);
the quick case always runs at its own 500.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from rich.console import Console
from rich.table import Table

from scm_core.calibration import PRESETS, preset_case, preset_cost
from scm_core.calibration.presets import stage_runs

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = {"quick": "quick.toml", "1": "case1.toml", "2a": "case2a.toml", "2b": "case2b.toml"}


def _run(key: str, samples: int | None, workers: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        case = str(ROOT / "examples" / EXAMPLE[key])
        cmd = [sys.executable, "-m", "services.cli", "calibrate", case, "--no-plots", "--quiet",
               "--workers", str(workers), "--out", f"{tmp}/out"]  # fmt: skip
        if samples is not None:
            cmd += ["--samples", str(samples)]
        subprocess.run(cmd, check=True, cwd=ROOT)
        return json.loads(Path(f"{tmp}/out/summary.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--presets", nargs="+", default=["quick", "1"], choices=list(PRESETS))
    ap.add_argument("--samples", type=int, default=500)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    subprocess.run(
        [sys.executable, "-m", "services.cli", "simulate", "--json"],
        check=True,
        capture_output=True,
        cwd=ROOT,
    )  # fmt: skip  (compile once)
    table = Table(title=f"preset studies on {args.workers} workers")
    for col in ("preset", "samples", "stages", "model runs", "planned", "share", "ms/sim",
                "wall s", "table: runs", "table: s"):  # fmt: skip
        table.add_column(col, justify="right")
    for key in args.presets:
        samples = None if key == "quick" else args.samples
        case = preset_case(key)
        if samples is not None:
            case = case.with_changes(sampler={"n_samples": samples})
        n, per_stage = case.sampler.n_samples, stage_runs(case)
        runs = [_run(key, samples, args.workers) for _ in range(args.repeats)]
        stages = statistics.median(r["n_stages"] for r in runs)
        model_runs = statistics.median(r["model_runs"] for r in runs)
        sims = statistics.median(r["simulations"] for r in runs)
        wall = statistics.median(r["wall_time_s"] for r in runs)
        cost = preset_cost(key, samples)
        table.add_row(
            key, str(n), f"{stages:g}", f"{model_runs:,.0f}", f"{n + stages * per_stage:,.0f}",
            f"{(model_runs - n) / (stages * per_stage):.2f}", f"{1e3 * wall / sims:.1f}",
            f"{wall:.0f}", f"{cost.model_runs:,}", f"{60 * cost.minutes:.0f}",
        )  # fmt: skip
    Console(width=150).print(table)


if __name__ == "__main__":
    main()
