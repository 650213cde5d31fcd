"""The transfer from straight driving with the calibration's spread: a joint case's posterior
predicting the steered CMU wheels, 95 % bands.

Run, after calibrating ``examples/cmu_joint.toml`` (about 90 min on two cores)::

    scm-calib calibrate examples/cmu_joint.toml --workers 2 --out cmu_joint_results
    scm-calib predict cmu_joint_results --data examples/cmu_steering/*/logs/*.csv
    python benchmarks/steering_bands.py cmu_joint_results/predictions/predictions.json

Reads ``scm-calib predict``'s ``predictions.json`` and prints, per slip angle and in all, at how
many conditions the measured F, Fy and z lie inside their 95 % bands (predictive where the study
has a sigma for the response, F and z; the simulated means' band for Fy, which the straight case
never saw), and at how many the band's median meets issue 70's criteria (F and Fy within
max(1.5 N, 20 % of |measured|), z within 3 mm: ``steering_transfer.met``). ``--rows`` prints
every condition.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections import defaultdict
from pathlib import Path

from rich.console import Console
from rich.table import Table

sys.path.insert(0, str(Path(__file__).resolve().parent))
from steering_transfer import met

NAME = re.compile(r"cmu_(smooth|grouser)_b(\d+)_v(\d+)")
RESPONSES = ("F", "Fy", "z")


def rows(doc: dict) -> list[dict]:
    """One row per steering dataset: wheel, angle, rim speed and per response the measured
    value, the band's median, whether the measured value is inside the band and whether the
    median meets the criterion."""
    out = []
    for d in doc["datasets"]:
        m = NAME.fullmatch(d["name"])
        if m is None:
            continue
        row = {"wheel": m[1], "beta": int(m[2]), "rim": int(m[3])}
        for r in RESPONSES:
            p = d["responses"].get(r)
            if p is None or p["measured"] is None:
                row[r] = None
                continue
            band = p["predictive"] or p["simulated"]
            inside = p["inside_predictive"]
            if inside is None:
                inside = p["inside_simulated"]
            median = band["median"]
            row[r] = {
                "measured": p["measured"],
                "median": median,
                "lo": band["lo"],
                "hi": band["hi"],
                "inside": bool(inside),
                "met": median is not None and met(median, p["measured"], "z" if r == "z" else "F"),
            }
        out.append(row)
    return sorted(out, key=lambda r: (r["wheel"] != "smooth", r["beta"], r["rim"]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("predictions", type=Path, help="scm-calib predict's predictions.json")
    ap.add_argument("--rows", action="store_true", help="print every condition")
    args = ap.parse_args()
    doc = json.loads(args.predictions.read_text())
    found = rows(doc)
    console = Console()
    if args.rows:
        t = Table(title="per condition: measured [median, 95 % band]")
        for col in ("wheel", "beta", "rim", *RESPONSES):
            t.add_column(col, justify="right")
        for r in found:
            cells = []
            for k in RESPONSES:
                p, s = r[k], 1e3 if k == "z" else 1.0
                cells.append(
                    "-"
                    if p is None
                    else f"{p['measured'] * s:.1f} [{p['median'] * s:.1f}, {p['lo'] * s:.1f}.."
                    f"{p['hi'] * s:.1f}]{' in' if p['inside'] else ''}"
                )
            t.add_row(r["wheel"], str(r["beta"]), str(r["rim"]), *cells)
        console.print(t)
    counts: dict[object, dict[str, list[int]]] = defaultdict(lambda: defaultdict(lambda: [0, 0, 0]))
    for r in found:
        for key in (r["beta"], "all"):
            for k in RESPONSES:
                if r[k] is not None:
                    c = counts[key][k]
                    c[0] += 1
                    c[1] += r[k]["inside"]
                    c[2] += r[k]["met"]
    t = Table(title=f"{doc['study']['case']}: {doc['draws']} posterior draws, 95 % bands")
    for col in ("beta [deg]", "conditions", *(f"{k} in band / met" for k in RESPONSES)):
        t.add_column(col, justify="right")
    for key in [*sorted((k for k in counts if k != "all"), key=float), "all"]:
        c = counts[key]
        n = max(v[0] for v in c.values())
        t.add_row(str(key), str(n), *(f"{c[k][1]} / {c[k][2]}" for k in RESPONSES))
    console.print(t)


if __name__ == "__main__":
    main()
