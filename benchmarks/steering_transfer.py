"""Transfer from straight driving to steering: the joint case's soil at the CMU slip angles.

Run: ``python benchmarks/steering_transfer.py [--angles 0,30,60,90] [--threads 2] [--json OUT]
[--figure PNG] [--lab-window] [--budget]``.

The soil of ``examples/cmu_joint.toml`` as committed (its posterior medians, docs/cmu-record.md
"The joint calibration with both", the model options of the case file) predicts the development
data of ``examples/cmu_steering/`` (``--data`` to point elsewhere): both CMU wheels at the
slip angles 0, 30, 60 and 90 deg, the smooth wheel at its nine rim speeds, the grousered one at
five, each run at the lab's conditions (carriage 10 mm/s, the commanded rim speed, the angle, the
condition's mean measured load). Prints per condition F (along the heading), Fy (along the axle,
+ against the side slip) and z against the measured means, whether each is met (F and Fy within
max(1.5 N, 20 % of |measured|), z within 3 mm: issue 70's transfer criteria), the run's status and
wall time, and per angle how many conditions meet each criterion. A point prediction at the
posterior medians, not a predictive band: it measures the physics, not the calibration's spread.
``--lab-window`` runs each condition for 75 s and averages over 70-75 s, the authors' window,
instead of the rig's default (two wheel diameters of travel, four for a locked wheel; an early
stop once settled). ``--budget`` adds a table of where the model's F and Fy come from
(swt.ForceBudget: normal and shear stresses along the heading, the shear along the axle, the
leading side's passive force, and the compaction's power with the share of it F_normal
pays). ``--figure`` draws the same rows: F, Fy and z against the rim speed, a column per
angle, the measured means with their trials' standard deviation and the model, both wheels
(docs/figures/steering_transfer.png).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict
from pathlib import Path

from rich.console import Console
from rich.table import Table

from scm_core.calibration import load_case
from scm_core.calibration.model import build_configs
from scm_core.simulator import simulate_swt

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cmu_joint.toml"
DATA = ROOT / "examples" / "cmu_steering"
#: cmu_joint.toml's posterior medians (seed 1, 2026-12-06; docs/cmu-record.md)
MEDIANS = {
    "k_phi": 2.86e6,
    "n": 1.30,
    "phi": 33.9,
    "J": 0.0097,
    "K": 3.55e6,
    "shear_band": 0.0176,
    "bearing_inclination": 1.84,
    "interface_friction": 0.849,
    "pocket_fill": 0.269,
}
Z_OFFSET = -0.0040  # m, the rig's datum (z_offset's median)
CARRIAGE = 0.010  # m/s
RADIUS = 0.058  # m, to the rim (the grouser base)
WHEELS = {"smooth": {"n_grousers": 0}, "grouser": {"n_grousers": 12, "grouser_height": 0.005}}


def conditions(data: Path, angles: set[float]) -> list[dict]:
    """The development conditions (one per wheel, angle and rim speed) with their means."""
    rows = []
    for wheel in WHEELS:
        with open(data / wheel / "by_condition.csv", newline="") as fh:
            for r in csv.DictReader(fh):
                if float(r["slip_angle_deg"]) in angles:
                    rows.append({"wheel": wheel, **{k: float(v) for k, v in r.items()}})
    return rows


#: the authors' averaging window (data README): 70-75 s of each run
LAB_WINDOW = {"duration": 75.0, "offset_F": 70.0, "offset_T": 70.0, "offset_z": 70.0}


def predict(row: dict, case) -> dict:
    """The model's steady F, Fy, z [N, N, m] at one condition (NaN unless the run is ok) and
    its force budget."""
    cond = {
        "slip": None,
        "W": row["normal_load_N_mean"],
        "R": RADIUS,
        "b": 0.05,
        "carriage_speed": CARRIAGE,
        "omega": row["vry_cmd_mmps"] / 1000.0 / RADIUS,
        "slip_angle": row["slip_angle_deg"],
        **WHEELS[row["wheel"]],
    }
    soil, wheel, rig = build_configs(case.nominal, case.simulator, cond, MEDIANS)
    t0 = time.perf_counter()
    res = simulate_swt(soil, wheel, rig)
    wall = time.perf_counter() - t0
    nan = float("nan")
    m = res.means
    return {
        "status": res.status,
        "wall_s": wall,
        "F": m.F if m else nan,
        "Fy": m.Fy if m else nan,
        "z": m.z + Z_OFFSET if m else nan,
        "budget": {**asdict(res.budget), "compaction_paid": res.budget.compaction_paid}
        if res.budget
        else None,
    }


def met(pred: float, meas: float, kind: str) -> bool:
    """Issue 70's transfer criteria: forces within max(1.5 N, 20 %), sinkage within 3 mm."""
    if kind == "z":
        return abs(pred - meas) <= 0.003
    return abs(pred - meas) <= max(1.5, 0.2 * abs(meas))


def draw(rows: list[dict], path: Path) -> None:
    """F, Fy and z [N, N, mm] against the rim speed, a column per angle: measured means (+- the
    trials' sd) and the model's steady means, both wheels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    angles = sorted({r["slip_angle_deg"] for r in rows})
    quantities = (
        ("F", "drawbar_pull_N", 1.0, "F along the heading [N]"),
        ("Fy", "lateral_force_N", 1.0, "Fy along the axle [N]"),
        ("z", "sinkage_m", 1e3, "sinkage z [mm]"),
    )
    fig, axes = plt.subplots(
        3, len(angles), figsize=(3.2 * len(angles), 8.4), sharex=True, sharey="row", squeeze=False
    )
    colours = {"smooth": "tab:blue", "grouser": "tab:orange"}
    for col, beta in enumerate(angles):
        for wheel, colour in colours.items():
            mine = sorted(
                (r for r in rows if r["wheel"] == wheel and r["slip_angle_deg"] == beta),
                key=lambda r: r["vry_cmd_mmps"],
            )
            rim = [r["vry_cmd_mmps"] for r in mine]
            for row, (key, column, scale, label) in enumerate(quantities):
                ax = axes[row, col]
                ax.errorbar(
                    rim,
                    [r[f"{column}_mean"] * scale for r in mine],
                    yerr=[r[f"{column}_sd"] * scale for r in mine],
                    fmt="o",
                    color=colour,
                    ms=4,
                    capsize=2,
                    label=f"{wheel}: measured" if col == 0 else None,
                )
                ax.plot(
                    rim,
                    [r[f"pred_{key}"] * scale for r in mine],
                    "-x",
                    color=colour,
                    lw=1,
                    label=f"{wheel}: model" if col == 0 else None,
                )
                if col == 0:
                    ax.set_ylabel(label)
        axes[0, col].set_title(f"slip angle {beta:.0f} deg")
        axes[-1, col].set_xscale("symlog", linthresh=10.0)
        axes[-1, col].set_xlabel("rim speed [mm/s] (carriage 10)")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("cmu_joint.toml's soil (posterior medians) predicting the steered CMU wheels")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def budget_table(rows: list[dict]) -> Table:
    """Where the model's F and Fy come from at each condition (swt.ForceBudget) [N]."""
    table = Table(title="where the model's forces come from [N] (swt.ForceBudget)")
    cols = ("wheel", "beta", "rim mm/s", "F", "normal", "shear", "heap", "F meas")
    for col in (*cols, "Fy", "shear y", "side", "Fy meas", "compaction mW", "paid"):
        table.add_column(col, justify="right")
    for r in rows:
        b = r["pred_budget"]
        if b is None:
            continue
        table.add_row(
            r["wheel"],
            f"{r['slip_angle_deg']:.0f}",
            f"{r['vry_cmd_mmps']:.0f}",
            *(f"{v:.1f}" for v in (r["pred_F"], b["F_normal"], b["F_shear"], b["F_heap"])),
            f"{r['drawbar_pull_N_mean']:.1f}",
            *(f"{v:.1f}" for v in (r["pred_Fy"], b["Fy_shear"], b["Fy_side"])),
            f"{r['lateral_force_N_mean']:.1f}",
            f"{b['compaction_power'] * 1e3:.0f}",
            "-" if math.isnan(b["compaction_paid"]) else f"{b['compaction_paid']:.0%}",
        )
    return table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--angles", default="0,30,60,90")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--json", type=Path, default=None, help="write the rows as JSON")
    ap.add_argument("--figure", type=Path, default=None, help="draw the rows (PNG)")
    ap.add_argument("--lab-window", action="store_true", help="average over 70-75 s, as the lab")
    ap.add_argument("--budget", action="store_true", help="print where F and Fy come from")
    args = ap.parse_args()
    case = load_case(CASE)
    if args.lab_window:
        case.simulator.pop("steady_tolerance", None)  # the whole 75 s, as the lab's runs
        case.simulator.update(LAB_WINDOW)
    rows = conditions(args.data, {float(a) for a in args.angles.split(",")})
    simulate_swt()  # compile before timing
    with ThreadPoolExecutor(args.threads) as pool:
        preds = list(pool.map(lambda r: predict(r, case), rows))
    table = Table(title="cmu_joint.toml's soil (posterior medians) at the development angles")
    for col in ("wheel", "beta", "rim mm/s", "F", "F meas", "Fy", "Fy meas", "z mm", "z meas"):
        table.add_column(col, justify="right")
    table.add_column("met (F Fy z)")
    table.add_column("status")
    table.add_column("s", justify="right")
    counts: dict[float, list[int]] = {}
    out = []
    for r, p in zip(rows, preds, strict=True):
        ok = (
            met(p["F"], r["drawbar_pull_N_mean"], "F"),
            met(p["Fy"], r["lateral_force_N_mean"], "F"),
            met(p["z"], r["sinkage_m_mean"], "z"),
        )
        c = counts.setdefault(r["slip_angle_deg"], [0, 0, 0, 0])
        c[0] += 1
        for i, o in enumerate(ok):
            c[i + 1] += int(o)
        table.add_row(
            r["wheel"],
            f"{r['slip_angle_deg']:.0f}",
            f"{r['vry_cmd_mmps']:.0f}",
            f"{p['F']:.2f}",
            f"{r['drawbar_pull_N_mean']:.2f}",
            f"{p['Fy']:.2f}",
            f"{r['lateral_force_N_mean']:.2f}",
            f"{p['z'] * 1e3:.1f}",
            f"{r['sinkage_m_mean'] * 1e3:.1f}",
            " ".join("y" if o else "-" for o in ok),
            p["status"],
            f"{p['wall_s']:.2f}",
        )
        out.append({**r, **{f"pred_{k}": v for k, v in p.items()}, "met": ok})
    console = Console()
    console.print(table)
    summary = Table(title="conditions met (F, Fy within max(1.5 N, 20 %); z within 3 mm)")
    for col in ("beta [deg]", "conditions", "F", "Fy", "z"):
        summary.add_column(col, justify="right")
    for beta, (n, f, fy, z) in sorted(counts.items()):
        summary.add_row(f"{beta:.0f}", str(n), str(f), str(fy), str(z))
    total = [sum(c[i] for c in counts.values()) for i in range(4)]
    summary.add_row("all", *map(str, total))
    console.print(summary)
    if args.budget:
        console.print(budget_table(out))
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    if args.figure:
        draw(out, args.figure)


if __name__ == "__main__":
    main()
