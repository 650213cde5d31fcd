"""Write the CMU steering runs (``runs.csv``) as lab files: one log per wheel, slip angle and rim
speed, its trials as rows (the form of ``../cmu_smooth/`` and ``../cmu_grouser/``, with the lateral
force and the slip angle), into ``smooth/logs/`` and ``grouser/logs/``.

Run: ``python examples/cmu_steering/make_lab_files.py`` (the files are committed; this says how
they were made). Conditions in each header as the lab set them: the commanded slip angle, the
trials' mean lab slip (symmetric convention), carriage speed and normal load; the wheel's radius
to the rim and its width; for the grousered wheel its 12 grousers of 5 mm.
"""

from __future__ import annotations

import csv
import statistics
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = (
    "robomechanics/3d-terramechanics, raw-data-processing/all_{wheel}_data.mat "
    "(C. Pavlov, A. M. Johnson, CMU; MIT licence)"
)
WHEELS = {"smooth": ["# grousers: 0"], "grouser": ["# grousers: 12", "# grouser_height: 5 mm"]}


def _conditions(rows: list[dict[str, str]]) -> dict[tuple[float, float], list[dict[str, str]]]:
    """The runs grouped by (slip angle [deg], commanded rim speed [mm/s]), in file order."""
    out: dict[tuple[float, float], list[dict[str, str]]] = {}
    for r in rows:
        out.setdefault((float(r["slip_angle_deg"]), float(r["vry_cmd_mmps"])), []).append(r)
    return out


def _mean(rows: list[dict[str, str]], key: str) -> float:
    return statistics.fmean(float(r[key]) for r in rows)


def lab_file(wheel: str, angle: float, rim: float, runs: list[dict[str, str]]) -> str:
    """One condition's runs as a lab log (``# key: value`` lines, then a row per trial)."""
    name = f"cmu_{wheel}_b{angle:02.0f}_v{rim:03.0f}"
    head = [
        f"# name: {name}",
        f"# source: {SOURCE.format(wheel=wheel)}",
        f"# rim speed command: {rim:g} mm/s",
        f"# slip_angle: {angle:g} deg",
        f"# slip: {_mean(runs, 'slip_lab'):.6g}",
        "# slip_convention: symmetric",
        f"# carriage_speed: {_mean(runs, 'carriage_speed_mmps'):.6g} mm/s",
        f"# normal_load: {_mean(runs, 'normal_load_N'):.6g} N",
        "# wheel_radius: 58 mm",
        "# wheel_width: 50 mm",
        *WHEELS[wheel],
        "# soil: dry sand, 1330 kg/m^3, angle of repose 29 deg",
        "trial,drawbar_pull [N],lateral_force [N],sinkage [m],normal_load [N],rim_speed [mm/s]",
    ]
    body = [
        f"{k},{r['drawbar_pull_N']},{r['lateral_force_N']},{r['sinkage_m']},{r['normal_load_N']},"
        f"{r['rim_speed_mmps']}"
        for k, r in enumerate(runs, 1)
    ]
    return "\n".join([*head, *body]) + "\n"


def main() -> None:
    for wheel in WHEELS:
        with open(HERE / wheel / "runs.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        logs = HERE / wheel / "logs"
        logs.mkdir(exist_ok=True)
        for (angle, rim), runs in _conditions(rows).items():
            text = lab_file(wheel, angle, rim, runs)
            name = text.splitlines()[0].removeprefix("# name: ")
            (logs / f"{name}.csv").write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
