"""Simulator cost where labs test: the paper wheel and CMU-like small wheels at the nine lab slips.

Run: ``python benchmarks/bench_lab_wheels.py [--repeats 3] [--draws 12]``. One core (numba's
single-run kernel), after a warm-up. Prints two tables:

* per wheel and lab slip, with the fixed soil k_phi 8e6, n 1.0, phi 29 deg, J 0.01 m (the CMU
  case's options: ``shear = "displacement"``, ``drive_digging = "mobilised"``,
  ``skid_ploughing = "sliding_face"``; the other calibrated parameters at their prior medians):
  median wall time of ``--repeats`` runs, steps, loaded nodes per step, contact evaluations per
  step (vertical solves), erosion visits per step, the share of the step's time per kernel phase
  (wheel envelope and contact patches, vertical solve, node update, flow fields and deposits,
  erosion; from the CPU's cycle counter) and the run's status;
* over ``--draws`` draws of the CMU case's prior at the five calibration rim speeds: mean, median
  and largest wall time per run and the share of runs that did not finish;
* with ``--angles 30,60,90`` (issue 70's cost of a steered wheel), the CMU smooth and rim-bearing
  grousered wheels at the five calibration rim speeds and each slip angle: median wall time and
  its ratio to the same wheel's straight run at the same rim speed, the step's phase shares and
  the status; per wheel and angle the median ratio and the largest wall time.

Every run averages its whole window: the CMU case's early stop of settled runs
(``steady_tolerance``) is left out, so the tables measure the simulator itself
(``benchmarks/bench_steady_stop.py`` measures what the early stop saves).

``benchmarks/bench_simulator.py`` prints these tables after its own (``--no-lab`` skips them).

Wheels: the paper's (its wheel, soil and rig at the nine slips), the CMU smooth wheel (R 58 mm,
b 50 mm, the datasets' loads and speeds from ``examples/cmu_smooth/``) and a CMU-like grousered
wheel built from the same rig (12 grousers of 5 mm), with its grousers as faces in the z-buffer
(``grouser_contact = "faces"``), as trapped soil on the tip circle (``"tip_circle"``) and as
blades whose rim bears (``"rim_bearing"``, the CMU cases'); every wheel's sinkage read from its
rim (the cases' ``sinkage_datum = "rim"``).
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
from scm_core.simulator import RigConfig, simulate_swt
from scm_core.slip import drive_to_symmetric

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cmu_smooth.toml"
DATA = sorted((ROOT / "examples" / "cmu_smooth").glob("cmu_smooth_s*.csv"))
CALIBRATION_STEMS = ("sm100", "sm050", "sp000", "sp050", "sp090")  # rim speeds 0-100 mm/s
SOIL = {"k_phi": 8.0e6, "n": 1.0, "phi": 29.0, "J": 0.01}
GROUSERS = {"n_grousers": 12, "grouser_height": 0.005}


def _slip_key(terms) -> float:
    return float(terms.conditions["slip"])


def _symmetric(terms) -> float:
    """The dataset's slip in the symmetric lab convention (-1 locked, 0 rolling, 1 spinning)."""
    c = terms.conditions
    s = float(c["slip"])
    return s if c.get("slip_convention") == "symmetric" else drive_to_symmetric(s)


PHASES = ("geometry", "solve", "commit", "flow", "erosion")


def _run(soil, wheel, rig) -> dict[str, float | str]:
    r = simulate_swt(soil, wheel, rig)
    d = r.diagnostics
    steps = max(d["steps"], 1.0)
    ticks = [d[f"cycles_{p}"] for p in PHASES]
    total = max(sum(ticks), 1.0)
    return {
        **{f"share_{p}": t / total for p, t in zip(PHASES, ticks, strict=True)},
        "wall": r.wall_time_s,
        "steps": d["steps"],
        "nodes": d["node_steps"] / steps,
        "evals": d["contact_evaluations"] / steps,
        "erosion": d["erosion_visits"] / steps,
        "status": r.status,
    }


def _median_run(cfg, repeats: int) -> dict[str, float | str]:
    runs = [_run(*cfg) for _ in range(repeats)]
    out = dict(runs[-1])
    out["wall"] = statistics.median(float(r["wall"]) for r in runs)
    return out


def _row(table: Table, wheel: str, slip: str, r: dict[str, float | str]) -> None:
    table.add_row(
        wheel,
        slip,
        f"{1000 * float(r['wall']):.0f}",
        f"{float(r['steps']):.0f}",
        f"{float(r['nodes']):.0f}",
        f"{float(r['evals']):.2f}",
        f"{float(r['erosion']):.0f}",
        " ".join(f"{100 * float(r[f'share_{p}']):2.0f}" for p in PHASES),
        str(r["status"]),
    )


def _cmu_setup():
    """(case, its datasets' terms by slip, model, simulator settings averaging the whole
    window, the prior's medians by name) of the CMU smooth case."""
    case = load_case(CASE)
    terms = sorted((dataset_terms(load_dataset(p)) for p in DATA), key=_slip_key)
    model = StudyModel(case, terms)
    simulator = {**model.simulator, "steady_tolerance": None}  # the whole window (see above)
    prior = case.prior()
    medians = prior.ppf(np.full((1, prior.dim), 0.5))[0]
    return case, terms, model, simulator, dict(zip(case.parameter_names, medians, strict=True))


def lab_tables(repeats: int, draws: int, seed: int) -> list[Table]:
    """The two tables of the module docstring (the JIT warmed up first)."""
    case, terms, model, simulator, base = _cmu_setup()
    prior = case.prior()
    wheels = {
        "CMU smooth": {},
        "CMU 12x5 mm faces": {**GROUSERS, "grouser_contact": "faces"},
        "CMU 12x5 mm tip circle": {**GROUSERS, "grouser_contact": "tip_circle"},
        "CMU 12x5 mm rim bearing": {**GROUSERS, "grouser_contact": "rim_bearing"},
    }
    simulate_swt()  # warm-up (JIT)

    fixed = Table(
        title="Lab slips (one core): the paper's wheel, soil and rig; the CMU wheels on the soil "
        "k_phi 8e6, n 1.0, phi 29 deg, J 0.01 m"
    )
    for col in ("wheel", "lab slip", "ms/run", "steps", "nodes/step", "evals/step"):
        fixed.add_column(col, justify="right")
    fixed.add_column("erosion visits/step", justify="right")
    fixed.add_column("% geom solve commit flow erosion", justify="right")
    fixed.add_column("status")
    for t in terms:  # the paper's set-up at the same nine slips (symmetric convention)
        rig = RigConfig(slip=round(_symmetric(t), 2), slip_convention="symmetric")
        _row(fixed, "paper", f"{_slip_key(t):+.2f}", _median_run((None, None, rig), repeats))
    for name, extra in wheels.items():
        for t in terms:
            cfg = build_configs(
                model.nominal, simulator, {**t.conditions, **extra}, {**base, **SOIL}
            )
            _row(fixed, name, f"{_slip_key(t):+.2f}", _median_run(cfg, repeats))

    rng = np.random.default_rng(seed)
    thetas = prior.sample(rng, draws)
    by_draws = Table(title=f"{draws} draws of the CMU case's prior (one core)")
    for col in ("wheel", "lab slip", "mean ms/run", "median", "max", "not finished"):
        by_draws.add_column(col, justify="right")
    for name, extra in wheels.items():
        for t in terms:
            if not t.name.endswith(CALIBRATION_STEMS):
                continue
            walls, failed = [], 0
            for theta in thetas:
                values = dict(zip(case.parameter_names, theta, strict=True))
                cfg = build_configs(model.nominal, simulator, {**t.conditions, **extra}, values)
                r = _run(*cfg)
                walls.append(float(r["wall"]))
                failed += r["status"] != "ok"
            by_draws.add_row(
                name,
                f"{_slip_key(t):+.2f}",
                f"{1000 * statistics.fmean(walls):.0f}",
                f"{1000 * statistics.median(walls):.0f}",
                f"{1000 * max(walls):.0f}",
                f"{failed}/{len(walls)}",
            )
    return [fixed, by_draws]


def angle_table(repeats: int, angles: list[float]) -> Table:
    """The steered wheels' cost against their straight runs (module doc, third table)."""
    _, terms, model, simulator, base = _cmu_setup()
    terms = [t for t in terms if t.name.endswith(CALIBRATION_STEMS)]
    values = {**base, **SOIL}
    wheels = {
        "CMU smooth": {},
        "CMU 12x5 mm rim bearing": {**GROUSERS, "grouser_contact": "rim_bearing"},
    }
    simulate_swt()  # warm-up (JIT)
    table = Table(title="Steered against straight (one core): ms/run and the ratio to 0 deg")
    for col in ("wheel", "lab slip", "angle", "ms/run", "x straight"):
        table.add_column(col, justify="right")
    table.add_column("% geom solve commit flow erosion", justify="right")
    table.add_column("status")
    for name, extra in wheels.items():
        ratios: dict[float, list[float]] = {a: [] for a in angles}
        walls: dict[float, list[float]] = {a: [] for a in angles}
        for t in terms:
            straight = None
            for a in [0.0, *angles]:
                cond = {**t.conditions, **extra, "slip_angle": a}
                r = _median_run(build_configs(model.nominal, simulator, cond, values), repeats)
                wall = float(r["wall"])
                straight = wall if a == 0.0 else straight
                if a:
                    ratios[a].append(wall / straight)
                    walls[a].append(wall)
                table.add_row(
                    name, f"{_slip_key(t):+.2f}", f"{a:g}", f"{1000 * wall:.0f}",
                    f"{wall / straight:.2f}",
                    " ".join(f"{100 * float(r[f'share_{p}']):2.0f}" for p in PHASES),
                    str(r["status"]),
                )  # fmt: skip
        for a in angles:
            table.add_row(
                name, "median", f"{a:g}", f"max {1000 * max(walls[a]):.0f}",
                f"{statistics.median(ratios[a]):.2f}", "", "",
            )  # fmt: skip
    return table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=3, help="runs per cell (median)")
    ap.add_argument("--draws", type=int, default=12, help="prior draws per rim speed")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--angles", default=None, help="slip angles [deg], e.g. 30,60,90: only the steered table"
    )
    args = ap.parse_args()
    if args.angles:
        angles = [float(a) for a in args.angles.split(",")]
        Console(width=160).print(angle_table(args.repeats, angles))
        return
    for table in lab_tables(args.repeats, args.draws, args.seed):
        Console(width=160).print(table)


if __name__ == "__main__":
    main()
