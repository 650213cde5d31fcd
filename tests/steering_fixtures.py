"""Steered test conditions from the real data (``examples/cmu_steering``, issue 70), shared by
the figure, API and browser tests: rows of the smooth wheel's ``by_condition.csv`` and each as
a lab summary file (what ``POST /datasets`` and ``load_summary`` read)."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

SMOOTH = Path(__file__).resolve().parents[1] / "examples" / "cmu_steering" / "smooth"


def cmu_rows(
    angles: Sequence[float], rim_speeds: Sequence[float] = (0.0, 10.0, 100.0)
) -> list[dict[str, float]]:
    """The smooth wheel's conditions at ``angles`` [deg] and commanded rim speeds [mm/s]
    (0: locked, 10: zero slip, 100: slip 0.9), in the file's order (by angle, then speed)."""
    with open(SMOOTH / "by_condition.csv", newline="") as fh:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    return [r for r in rows if r["slip_angle_deg"] in angles and r["vry_cmd_mmps"] in rim_speeds]


def cmu_name(row: dict[str, float]) -> str:
    """A row's dataset name: "cmu 30deg 100mmps"."""
    return f"cmu {row['slip_angle_deg']:g}deg {row['vry_cmd_mmps']:g}mmps"


def cmu_summary(row: dict[str, float]) -> str:
    """A row as a lab summary file: the three trials' means and sds of F, Fy and z at the
    rig's conditions (carriage 10 mm/s, the wheel of 58 mm radius and 50 mm width)."""
    return (
        f"# name: {cmu_name(row)}\n"
        f"# slip_angle: {row['slip_angle_deg']:g} deg\n"
        f"# normal_load: {row['normal_load_N_mean']} N\n"
        f"# slip: {row['slip_lab_mean']}\n# slip_convention: symmetric\n"
        "# carriage_speed: 10 mm/s\n# wheel_radius: 58 mm\n# wheel_width: 50 mm\n# grousers: 0\n"
        f"# n_trials: {row['n_trials']:g}\n"
        "response,mean,sd,unit\n"
        f"drawbar_pull,{row['drawbar_pull_N_mean']},{row['drawbar_pull_N_sd']},N\n"
        f"lateral_force,{row['lateral_force_N_mean']},{row['lateral_force_N_sd']},N\n"
        f"sinkage,{row['sinkage_m_mean']},{row['sinkage_m_sd']},m\n"
    )
