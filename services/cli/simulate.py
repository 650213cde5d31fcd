"""``scm-calib simulate``: one SCM single-wheel test from the command line."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import asdict
from pathlib import Path

import click
from rich.console import Console
from rich.table import Table

from scm_core.simulator import SWTResult, simulate_swt

from .overrides import OverrideError, build_configs, set_option


@click.command()
@set_option("Change one soil, wheel or rig value (SI units, angles in degrees), e.g. --set phi=28.")
@click.option(
    "--out", type=click.Path(dir_okay=False, path_type=Path), help="Write the series (CSV)."
)
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), help="Draw F, T, z (PNG).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
def simulate(
    overrides: tuple[str, ...], out: Path | None, plot: Path | None, as_json: bool
) -> None:
    """Simulate a single-wheel test; the defaults are the paper's set-up (WF34, 315 N, s 0.2)."""
    try:
        soil, wheel, rig = build_configs(overrides)
    except OverrideError as exc:
        raise click.UsageError(str(exc)) from None
    result = simulate_swt(soil, wheel, rig)
    if out is not None:
        write_series_csv(result, out)
    if plot is not None:
        from services.plots.swt import plot_swt

        plot_swt(result, plot, wheel=wheel)
    summary = result_summary(result)
    if as_json:
        summary["config"] = {
            "soil": soil.model_dump(),
            "wheel": wheel.model_dump(),
            "rig": rig.model_dump(),
            "resolved_rig": result.rig.to_dict(),
        }
        click.echo(json.dumps(summary, indent=2))
    else:
        _print_table(summary, result)
    if not result.ok:
        raise SystemExit(1)


def result_summary(result: SWTResult) -> dict:
    """JSON-ready means (F_mean N, T_mean N m, z_mean m; Fy_mean N of a steered wheel), status
    and run statistics."""
    m = result.means
    d = result.diagnostics
    return {
        "status": result.status,
        "F_mean": m.F if m else None,
        "T_mean": m.T if m else None,
        "z_mean": m.z if m else None,
        "Fy_mean": m.Fy if m else None,
        "force_budget": _budget(result),
        "wall_time_s": result.wall_time_s,
        "steps": int(d["steps"]),
        "mean_loaded_nodes": d["node_steps"] / max(d["steps"], 1.0),
        "compacted_volume_m3": d["compacted_volume"],
    }


def _budget(result: SWTResult) -> dict | None:
    """The force budget as JSON (swt.ForceBudget's fields and the compaction's share F_normal
    pays; None where there is no compaction to pay for)."""
    b = result.budget
    if b is None:
        return None
    paid = b.compaction_paid
    return {**asdict(b), "compaction_paid": None if math.isnan(paid) else paid}


def write_series_csv(result: SWTResult, path: Path) -> None:
    """Series as CSV in the lab-log column convention (SI units in brackets); a steered
    wheel's adds its lateral force."""
    cols = (
        ("time [s]", "t"),
        ("drawbar_pull [N]", "F"),
        ("torque [Nm]", "T"),
        ("sinkage [m]", "z"),
        ("normal_force [N]", "normal_force"),
        ("slip [-]", "slip"),
    ) + ((("lateral_force [N]", "Fy"),) if result.rig.slip_angle else ())
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow([c for c, _ in cols])
        series = [result.series[k] for _, k in cols]
        for row in zip(*series, strict=True):
            writer.writerow([f"{v:.9g}" for v in row])


#: the drawbar pull's parts in the table (ForceBudget's fields)
_F_PARTS = (
    ("F_normal", "normal stresses (compaction, bulldozing)"),
    ("F_shear", "shear stresses (thrust, drag)"),
    ("F_cap", "Coulomb cap on the thrust"),
    ("F_heap", "bow wave's own wedge"),
)


def _print_table(summary: dict, result: SWTResult) -> None:
    rig = result.rig
    kin = (
        f"carriage {rig.carriage_speed * 1000:.4g} mm/s, rim {rig.rim_speed * 1000:.4g} mm/s, "
        f"slip {rig.slip_symmetric:.4g} (symmetric)"
    )
    table = Table(title=f"SCM single-wheel test: {summary['status']}", caption=kin)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_column("window")

    def fmt(v, scale=1.0, unit=""):
        return "-" if v is None else f"{v * scale:.4g} {unit}"

    table.add_row("drawbar pull F", fmt(summary["F_mean"], unit="N"), f"t >= {rig.offset_F:g} s")
    budget = summary["force_budget"]
    if budget:  # where F comes from (swt.ForceBudget)
        for key, label in _F_PARTS:
            if key in ("F_normal", "F_shear") or budget[key] != 0.0:
                table.add_row(f"  {label}", fmt(budget[key], unit="N"), "")
        if budget["compaction_power"] > 0.0:  # the energy the soil's compaction takes
            table.add_row(
                "  compaction's power",
                fmt(budget["compaction_power"], 1e3, "mW"),
                f"{budget['compaction_paid']:.0%} paid by F",
            )
    table.add_row("torque T", fmt(summary["T_mean"], unit="N m"), f"t >= {rig.offset_T:g} s")
    table.add_row("sinkage z", fmt(summary["z_mean"], 1000.0, "mm"), f"t >= {rig.offset_z:g} s")
    if rig.slip_angle:
        fy = fmt(summary["Fy_mean"], unit="N")
        table.add_row(f"lateral force Fy ({rig.slip_angle:g} deg)", fy, f"t >= {rig.offset_F:g} s")
        if budget:
            table.add_row("  shear along the axle", fmt(budget["Fy_shear"], unit="N"), "")
            table.add_row("  side's passive force", fmt(budget["Fy_side"], unit="N"), "")
    table.add_row("wall time", f"{summary['wall_time_s']:.3f} s", "")
    Console().print(table)
