"""Early stop of settled runs (``RigConfig.steady_tolerance``): steps saved and means moved.

Run: ``python benchmarks/bench_steady_stop.py [--draws 12] [--tolerances 0.01 0.005]``. One
core. For the CMU case (``examples/cmu_smooth.toml``: its wheel, options and calibration
datasets at lab slips -0.5, 0, 0.5, 0.9) over ``--draws`` draws of its prior, each run once
with the whole window and once per tolerance; prints per tolerance and slip the mean share of
the steps run, the share of runs that stopped early, and the largest change of the steady means
against the whole window (F in % of W, z in mm), then the calibration's mean over all four
slips (the share of simulator time it would take, steps standing for time).
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from scm_core.calibration import load_case
from scm_core.calibration.model import StudyModel, build_configs, dataset_terms
from scm_core.signals import load_dataset
from scm_core.simulator import simulate_swt

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cmu_smooth.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--draws", type=int, default=12, help="prior draws")
    ap.add_argument("--tolerances", type=float, nargs="+", default=[0.01, 0.005])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    case = load_case(CASE)
    terms = [dataset_terms(load_dataset(p)) for p in case.data_paths()]
    model = StudyModel(case, terms)
    prior = case.prior()
    thetas = prior.sample(np.random.default_rng(args.seed), args.draws)
    simulate_swt()  # warm-up (JIT)
    rows: dict[tuple[float, float], list[tuple[float, float, float]]] = {}
    for theta in thetas:
        values = dict(zip(case.parameter_names, theta, strict=True))
        for t in terms:
            soil, wheel, rig = build_configs(model.nominal, model.simulator, t.conditions, values)
            whole = simulate_swt(soil, wheel, rig.model_copy(update={"steady_tolerance": None}))
            if not whole.ok:
                continue
            for tol in args.tolerances:
                r = simulate_swt(soil, wheel, rig.model_copy(update={"steady_tolerance": tol}))
                if not r.ok:
                    continue
                share = r.diagnostics["steps"] / whole.diagnostics["steps"]
                dF = 100.0 * abs(r.means.F - whole.means.F) / whole.rig.W
                dz = 1000.0 * abs(r.means.z - whole.means.z)
                slip = float(t.conditions["slip"])
                rows.setdefault((tol, slip), []).append((share, dF, dz))
    table = Table(title=f"Early stop over {args.draws} prior draws of the CMU case (one core)")
    for col in ("tolerance", "lab slip", "runs", "steps run", "stopped early", "max |dF| % W"):
        table.add_column(col, justify="right")
    table.add_column("max |dz| mm", justify="right")
    for tol in args.tolerances:
        every = []
        for (t, slip), vals in sorted(rows.items()):
            if t != tol:
                continue
            every += vals
            table.add_row(*_cells(f"{tol:g}", f"{slip + 0.0:+.2f}", vals))
        table.add_row(*_cells(f"{tol:g}", "all", every), end_section=True)
    Console(width=120).print(table)


def _cells(tol: str, slip: str, vals: list[tuple[float, float, float]]) -> list[str]:
    shares = [v[0] for v in vals]
    return [
        tol,
        slip,
        str(len(vals)),
        f"{statistics.fmean(shares):.2f}",
        f"{sum(s < 1.0 for s in shares)}/{len(shares)}",
        f"{max(v[1] for v in vals):.2f}",
        f"{max(v[2] for v in vals):.2f}",
    ]


if __name__ == "__main__":
    main()
