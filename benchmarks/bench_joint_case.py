"""What the joint CMU case's physics options cost: its fourteen runs with each option off and on.

Run: ``python benchmarks/bench_joint_case.py [--repeats 5]``. One core (numba's single-run
kernel), after a warm-up. The fourteen datasets of ``examples/cmu_joint.toml`` (the CMU smooth
wheel's nine slips, the grousered wheel's five) at one soil near the joint posterior's median,
with the case's simulator settings but its early stop (the tables measure the simulator), and
with the bow wave's weight off (``bulk_density`` 0) or on (the case's 1330 kg/m^3) and the
grousered wheel's tips sliding as ``grouser_slip = "rim"`` or ``"rim_drive"``. Prints, per run
and variant, the median wall time of ``--repeats`` runs [ms] and the steady drawbar pull [N], and
the total over the fourteen.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

from rich.console import Console
from rich.table import Table

from scm_core.calibration import load_case
from scm_core.calibration.model import StudyModel, build_configs, dataset_terms
from scm_core.signals import load_dataset
from scm_core.simulator import simulate_swt

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cmu_joint.toml"
#: near the joint posterior's median (docs/cmu-record.md, "One soil for both wheels")
SOIL = dict(k_phi=3.0e6, n=1.28, phi=34.0, J=0.010, K=4.5e6, shear_band=0.017,
            bearing_inclination=1.8, interface_friction=0.87, pocket_fill=0.27)  # fmt: skip
VARIANTS = {
    "weightless, rim": (0.0, "rim"),
    "bow wave, rim": (1330.0, "rim"),
    "bow wave, rim_drive": (1330.0, "rim_drive"),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    case = load_case(CASE)
    terms = [dataset_terms(load_dataset(p)) for p in case.data_paths()]
    model = StudyModel(case, terms)
    simulator = {**model.simulator, "steady_tolerance": None}
    table = Table(title=f"joint case, median of {args.repeats} runs on one core")
    table.add_column("dataset")
    for name in VARIANTS:
        table.add_column(f"{name} [ms]", justify="right")
        table.add_column("F [N]", justify="right")
    totals = dict.fromkeys(VARIANTS, 0.0)
    for t in terms:
        row = [t.name]
        for name, (rho, slip) in VARIANTS.items():
            sim = {**simulator, "grouser_slip": slip}
            cfg = build_configs(model.nominal, sim, t.conditions, {**SOIL, "bulk_density": rho})
            simulate_swt(*cfg)  # warm-up (and the compile, once)
            runs = [simulate_swt(*cfg) for _ in range(args.repeats)]
            wall = statistics.median(r.wall_time_s for r in runs)
            totals[name] += wall
            f = runs[0].means.F if runs[0].ok else float("nan")
            row += [f"{1e3 * wall:.0f}", f"{f:.2f}"]
        table.add_row(*row)
    total_row = ["total"]
    for name in VARIANTS:
        total_row += [f"{1e3 * totals[name]:.0f}", ""]
    table.add_row(*total_row)
    Console(width=160).print(table)


if __name__ == "__main__":
    main()
