"""Simulator benchmark: wall time per default SWT, cost per loaded node, JIT cache, batch scaling.

Run: ``python benchmarks/bench_simulator.py [--repeats 7] [--batch 8] [--no-lab]``. Prints a table;
medians of ``--repeats`` runs after a warm-up. Compile times are measured in fresh interpreters
with an empty and then a filled NUMBA_CACHE_DIR. Then, unless ``--no-lab``, the per-slip tables of
``bench_lab_wheels.py``: the paper wheel, the CMU smooth wheel and a CMU-like grousered wheel at
the nine lab slips (wall time on one core, steps, loaded nodes and contact evaluations per step,
the share of each kernel phase) and over ``--draws`` draws of the CMU case's prior.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numba
from bench_lab_wheels import lab_tables
from rich.console import Console
from rich.table import Table

from scm_core.simulator import (
    RigConfig,
    SoilParams,
    WheelGeometry,
    resolve_rig,
    simulate_batch,
    simulate_swt,
)

_FIRST_CALL = """
import time
t0 = time.perf_counter()
from scm_core.simulator import (
    RigConfig,
    SoilParams,
    WheelGeometry,
    resolve_rig,
    simulate_batch,
    simulate_swt,
)
simulate_swt(rig=RigConfig(duration=2.0, offset_F=1.0, offset_T=1.0, offset_z=0.5))
simulate_batch([SoilParams()], rigs=RigConfig(duration=2.0, offset_F=1.0, offset_T=1.0,
               offset_z=0.5))
print(time.perf_counter() - t0)
"""


def first_call_seconds(cache_dir: str) -> float:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run(
        [sys.executable, "-c", _FIRST_CALL], env=env, capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip().splitlines()[-1])


def single_runs(repeats: int) -> tuple[float, float, dict]:
    simulate_swt()  # warm-up (JIT)
    walls, per_node = [], []
    for _ in range(repeats):
        r = simulate_swt()
        walls.append(r.wall_time_s)
        per_node.append(r.wall_time_s / r.diagnostics["node_steps"] * 1e9)
    return statistics.median(walls), statistics.median(per_node), r.diagnostics


def batch_throughput(n_runs: int, threads: int, repeats: int) -> float:
    numba.set_num_threads(threads)
    soils = [SoilParams(phi=28.0 + 0.5 * i) for i in range(n_runs)]
    simulate_batch(soils[:threads])
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        simulate_batch(soils)
        rates.append(n_runs / (time.perf_counter() - t0))
    return statistics.median(rates)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--batch", type=int, default=8, help="runs per batch call")
    ap.add_argument("--lab", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--lab-repeats", type=int, default=3, help="runs per lab-slip cell (median)")
    ap.add_argument("--draws", type=int, default=12, help="prior draws per calibration slip")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as cache:
        cold = first_call_seconds(cache)
        warm = first_call_seconds(cache)
    wall, ns_node, diag = single_runs(args.repeats)
    steps = diag["steps"]
    one = batch_throughput(args.batch, 1, max(3, args.repeats // 2))
    cores = numba.config.NUMBA_NUM_THREADS
    many = batch_throughput(args.batch, cores, max(3, args.repeats // 2))
    rig = resolve_rig(WheelGeometry(), RigConfig())
    table = Table(
        title=f"SCM SWT simulator (default run: {rig.duration:g} s, dt {rig.dt:g} s, "
        f"dx {rig.dx * 1000:g} mm)"
    )
    table.add_column("measure")
    table.add_column("value", justify="right")
    table.add_row(f"wall time per default run (median of {args.repeats})", f"{wall * 1000:.1f} ms")
    table.add_row("steps per run", f"{steps:.0f}")
    table.add_row("loaded nodes per step (mean)", f"{diag['node_steps'] / steps:.0f}")
    table.add_row(
        "contact evaluations per step (mean)", f"{diag['contact_evaluations'] / steps:.2f}"
    )
    table.add_row("ns per loaded node per step", f"{ns_node:.0f}")
    table.add_row("first call, empty JIT cache", f"{cold:.2f} s")
    table.add_row("first call, disk cache filled", f"{warm:.2f} s")
    table.add_row("batch throughput, 1 thread", f"{one:.2f} runs/s")
    table.add_row(f"batch throughput, {cores} threads", f"{many:.2f} runs/s ({many / one:.2f}x)")
    Console().print(table)
    if args.lab:
        for lab in lab_tables(args.lab_repeats, args.draws, seed=0):
            Console(width=160).print(lab)


if __name__ == "__main__":
    main()
