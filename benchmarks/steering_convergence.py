"""Convergence of a steered wheel's steady means under refinement (docs/simulator.md).

Run: ``python benchmarks/steering_convergence.py [--angle 45] [--slip 0.2]``. The paper's wheel
and soil with the bow wave's weight (``bulk_density`` 1330 kg/m^3), at the slip angle and slip
given, at the derived numerics (dx 5 mm, dt 20 ms) and with dx and dt halved together twice;
prints a markdown table of F, T, z, Fy and the run's wall time (after a compile run).
"""

from __future__ import annotations

import argparse
import time

from scm_core.simulator import RigConfig, SoilParams, simulate_swt

STEPS = ((0.005, 0.02), (0.0025, 0.01), (0.00125, 0.005))  # (dx [m], dt [s])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--angle", type=float, default=45.0, help="slip angle [deg]")
    ap.add_argument("--slip", type=float, default=0.2)
    args = ap.parse_args()
    soil = SoilParams(bulk_density=1330.0)
    simulate_swt(soil, rig=RigConfig(slip=args.slip, slip_angle=args.angle))  # compile
    print("| dx | dt | F [N] | T [N m] | z [mm] | Fy [N] | wall [s] |")
    print("|---|---|---|---|---|---|---|")
    for dx, dt in STEPS:
        rig = RigConfig(slip=args.slip, slip_angle=args.angle, dx=dx, dt=dt)
        t0 = time.perf_counter()
        r = simulate_swt(soil, rig=rig)
        wall = time.perf_counter() - t0
        if not r.ok:
            print(f"| {dx * 1e3:g} mm | {dt * 1e3:g} ms | {r.status} | | | | {wall:.2f} |")
            continue
        m = r.means
        print(
            f"| {dx * 1e3:g} mm | {dt * 1e3:g} ms | {m.F:.2f} | {m.T:.3f} | {m.z * 1e3:.2f} "
            f"| {m.Fy:.2f} | {wall:.2f} |"
        )


if __name__ == "__main__":
    main()
