"""Convergence of the steady means under time-step and grid refinement (docs/simulator.md tables).

Run: ``python benchmarks/convergence.py [--wheel paper|cmu] [--slip S ...]``. For each slip
(symmetric lab convention) it simulates the set-up at the derived numerics (``resolve_rig``) and
at dt and dx scaled by the factors below, and prints a markdown table of F, T, z (the row in bold
is the default). ``paper``: the paper's wheel, soil and rig; ``cmu``: the CMU smooth wheel (r 58
mm, b 50 mm, W 22 N, 10 mm/s) on a sand near its calibration (k* 2e6, n 1.1, phi 25 deg, J 5 mm/s,
K 7e6 Pa/m, shear band 13 mm, bearing inclination m 2, repose 29 deg; sinkage averaged over the
window of F, as in its case); ``cmu-grousers``: the same rig and sand with a CMU-like grousered
wheel (12 grousers of 5 mm on the 58 mm rim).
"""

from __future__ import annotations

import argparse

from scm_core.simulator import (
    RigConfig,
    SoilParams,
    WheelGeometry,
    resolve_rig,
    simulate_batch,
)

#: (dt factor, dx factor) relative to the derived numerics; (1, 1) is the default
REFINEMENTS = ((2.0, 1.0), (1.0, 1.0), (0.5, 1.0), (0.25, 1.0), (0.5, 2.0), (0.5, 0.5), (0.25, 0.5))

SETUPS = {
    "paper": (SoilParams(), WheelGeometry(), {}),
    "cmu": (
        SoilParams(
            k_c=0.0,
            k_phi=2.0e6,
            n=1.1,
            phi=25.0,
            c=0.0,
            J=0.005,
            K=7.0e6,
            shear_band=0.013,
            bearing_inclination=2.0,
            repose_angle=29.0,
        ),
        WheelGeometry(R=0.058, b=0.05, n_grousers=0),
        {"W": 22.0, "carriage_speed": 0.01, "offset_z_fraction": 0.4},
    ),
}
SETUPS["cmu-grousers"] = (
    SETUPS["cmu"][0],
    WheelGeometry(R=0.058, b=0.05, n_grousers=12, grouser_height=0.005),
    SETUPS["cmu"][2],
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wheel", choices=sorted(SETUPS), default="paper")
    ap.add_argument("--slip", type=float, nargs="+", default=[0.2])
    args = ap.parse_args()
    soil, wheel, rig_kw = SETUPS[args.wheel]
    for slip in args.slip:
        base = RigConfig(slip=slip, slip_convention="symmetric", **rig_kw)
        res = resolve_rig(wheel, base)
        rigs = [
            base.model_copy(update={"dt": res.dt * fdt, "dx": res.dx * fdx})
            for fdt, fdx in REFINEMENTS
        ]
        out = simulate_batch([soil] * len(rigs), wheel, rigs)
        print(
            f"\n{args.wheel} wheel, slip {slip:g} (symmetric), "
            f"default dt {res.dt:g} s, dx {res.dx * 1e3:g} mm\n"
        )
        print("| dt [s] | dx [mm] | F [N] | T [N m] | z [mm] | status |")
        print("|---|---|---|---|---|---|")
        for (fdt, fdx), rig, m, st in zip(REFINEMENTS, rigs, out.means, out.status, strict=True):
            b = "**" if (fdt, fdx) == (1.0, 1.0) else ""
            print(
                f"| {b}{rig.dt:.4g}{b} | {b}{rig.dx * 1e3:.3g}{b} | {m[0]:.2f} | {m[1]:.3f} "
                f"| {m[2] * 1e3:.2f} | {st} |"
            )


if __name__ == "__main__":
    main()
