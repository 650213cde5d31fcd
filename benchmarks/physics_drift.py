"""Steady means of a fixed set of runs, saved and compared: does a numerics change move the physics?

Run: ``python benchmarks/physics_drift.py --save before.json`` on the old code, then
``python benchmarks/physics_drift.py --compare before.json`` on the new. The runs (issue 42's
acceptance set): the paper's default run; the CMU smooth wheel and a CMU-like grousered wheel
(12 x 5 mm) at the nine lab slips with the soil k_phi 8e6, n 1.0, phi 29 deg, J 0.01 m (the CMU
case's options); and 20 soils drawn from the paper's Table 2 prior (case 1, seed 0) on the paper's
wheel and rig. Prints, per run, the steady F and T as a share of the wheel load W [%] and z [mm]
(new minus old) and flags a run that moved by more than 1 % of W or 0.3 mm, or changed status.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_lab_wheels import CASE, DATA, GROUSERS, SOIL, _slip_key

from scm_core.calibration import load_case
from scm_core.calibration.model import StudyModel, build_configs, dataset_terms
from scm_core.inference.priors import table2_prior
from scm_core.signals import load_dataset
from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, simulate_swt

F_TOL = 0.01  # of W
Z_TOL = 3e-4  # m


def run_set() -> dict[str, dict]:
    """name -> {status, F, T, z, W} for the acceptance set."""
    runs: dict[str, tuple] = {"paper default": (SoilParams(), WheelGeometry(), RigConfig())}
    case = load_case(CASE)
    terms = sorted((dataset_terms(load_dataset(p)) for p in DATA), key=_slip_key)
    model = StudyModel(case, terms)
    prior = case.prior()
    base = dict(zip(case.parameter_names, prior.ppf(np.full((1, prior.dim), 0.5))[0], strict=True))
    faces = {**GROUSERS, "grouser_contact": "faces"}  # the set as issue 42 fixed it
    for wheel, extra in (("smooth", {}), ("12x5", faces)):
        for t in terms:
            cfg = build_configs(
                model.nominal, model.simulator, {**t.conditions, **extra}, {**base, **SOIL}
            )
            runs[f"CMU {wheel} {_slip_key(t):+.2f}"] = cfg
    t2 = table2_prior("1")
    draws = t2.sample(np.random.default_rng(0), 20)
    for i, theta in enumerate(draws):
        v = dict(zip(t2.names, theta, strict=True))
        soil = SoilParams(k_c=v["k_c"], k_phi=v["k_phi"], n=v["n"], phi=v["phi"], J=v["J"])
        runs[f"table2 #{i:02d}"] = (soil, WheelGeometry(), RigConfig())
    simulate_swt(rig=RigConfig(duration=0.2, dt=0.02, offset_F=0.0, offset_T=0.0, offset_z=0.0))
    out = {}
    for name, (soil, wheel, rig) in runs.items():
        r = simulate_swt(soil, wheel, rig)
        m = r.means
        out[name] = {
            "status": r.status,
            "W": r.rig.W,
            "F": None if m is None else m.F,
            "T": None if m is None else m.T,
            "z": None if m is None else m.z,
            "steps": r.diagnostics["steps"],
            "wall": r.wall_time_s,
        }
    return out


def compare(old: dict, new: dict) -> int:
    table = Table(title="new - old: steady means (flag: > 1 % W or > 0.3 mm, or status)")
    columns = ("run", "status", "dF %W", "dT (N m)", "dz mm", "steps old/new", "ms old/new", "flag")
    for col in columns:
        table.add_column(col, justify="right")
    flagged = 0
    for name, o in old.items():
        n = new[name]
        if o["F"] is None or n["F"] is None:
            same = o["status"] == n["status"]
            flagged += not same
            status = n["status"] if same else f"{o['status']}->{n['status']}"
            table.add_row(name, status, "", "", "", "", "", "" if same else "!")
            continue
        dF = (n["F"] - o["F"]) / o["W"]
        dz = n["z"] - o["z"]
        bad = abs(dF) > F_TOL or abs(dz) > Z_TOL
        flagged += bad
        table.add_row(
            name,
            n["status"],
            f"{100 * dF:+.2f}",
            f"{n['T'] - o['T']:+.4f}",
            f"{1000 * dz:+.3f}",
            f"{o['steps']:.0f}/{n['steps']:.0f}",
            f"{1000 * o['wall']:.0f}/{1000 * n['wall']:.0f}",
            "!" if bad else "",
        )
    Console(width=120).print(table)
    print(f"{flagged} of {len(old)} runs moved beyond the tolerance")
    return flagged


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--save", type=Path)
    ap.add_argument("--compare", type=Path)
    args = ap.parse_args()
    new = run_set()
    if args.save:
        args.save.write_text(json.dumps(new, indent=1))
    if args.compare:
        compare(json.loads(args.compare.read_text()), new)


if __name__ == "__main__":
    main()
