"""A calibration as a user runs it from the command line, this checkout against another commit.

Run: ``python benchmarks/bench_cli.py [--case examples/quick.toml] [--repeats 3] [--workers 2]
[--baseline REF]``.

``scm-calib calibrate CASE --no-plots --quiet`` into a fresh results folder, in-process and on
``--workers`` processes, ``--repeats`` times each; the table gives per tree and mode the
median wall time of the whole process [s] (start, the study, the files), the stages, model runs
and log evidence (the same in every row: the results do not depend on the tree or the mode,
and a row that differs is marked). Each tree's simulator is compiled into its numba cache
before the timed runs. With ``--baseline REF`` the runs alternate between this checkout and a
git worktree of REF, so both share the machine's noise.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_startup import checkouts, compile_simulator
from rich.console import Console
from rich.table import Table


def _env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree)}


def calibrate(tree: Path, case: str, workers: int | None) -> tuple[float, tuple]:
    """(seconds, (stages, model runs, log evidence)) of one calibration in a fresh folder."""
    with tempfile.TemporaryDirectory(prefix="bench-cli-") as tmp:
        out = Path(tmp) / "results"
        cmd = [sys.executable, "-m", "services.cli", "calibrate", case, "--no-plots", "--quiet"]
        cmd += ["--out", str(out)] + ([] if workers is None else ["--workers", str(workers)])
        t0 = time.perf_counter()
        subprocess.run(cmd, cwd=tree, env=_env(tree), check=True, stdout=subprocess.DEVNULL)
        seconds = time.perf_counter() - t0
        s = json.loads((out / "summary.json").read_text())
    return seconds, (s["n_stages"], s["model_runs"], s["log_evidence"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="examples/quick.toml", help="case file, from the tree")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--baseline", help="git ref to compare with (run from a worktree)")
    args = ap.parse_args()
    modes = {"in-process": None, f"--workers {args.workers}": args.workers}
    times: dict[tuple[str, str], list[float]] = {}
    outcome: dict[tuple[str, str], tuple] = {}
    with checkouts(args.baseline) as trees:
        for tree in trees.values():
            compile_simulator(tree)
        for _ in range(args.repeats):
            for name, tree in trees.items():
                for mode, workers in modes.items():
                    seconds, result = calibrate(tree, args.case, workers)
                    times.setdefault((name, mode), []).append(seconds)
                    outcome[(name, mode)] = result
    first = next(iter(outcome.values()))
    table = Table(title=f"scm-calib calibrate {args.case}, median of {args.repeats} [s]")
    for col in ("tree", "mode", "median s", "runs s", "stages", "model runs", "log Z", "same"):
        table.add_column(col, justify="left" if col in ("tree", "mode") else "right")
    for (name, mode), ts in times.items():
        stages, runs, log_z = outcome[(name, mode)]
        table.add_row(
            name,
            mode,
            f"{statistics.median(ts):.1f}",
            " ".join(f"{t:.1f}" for t in ts),
            str(stages),
            str(runs),
            f"{log_z:.6g}",
            "yes" if outcome[(name, mode)] == first else "NO",
        )
    Console(width=120).print(table)


if __name__ == "__main__":
    main()
