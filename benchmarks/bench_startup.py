"""Start-up benchmark: what each kind of process pays before its first piece of work.

Run: ``python benchmarks/bench_startup.py [--repeats 5] [--baseline REF]``.

Every process of the service imports its entry module first: the API (``services.api.main``),
an embedded pool process or a Celery worker (``worker.runtime``), the CLI's calibration
(``services.cli.calibrate``), a figure process (``services.api.dashboard.study_figures`` plus its
plots). Each is imported in a fresh interpreter ``--repeats`` times, after a warm-up that fills
the bytecode caches and compiles the simulator into a fresh worktree's numba cache; the table
gives the median wall time [s] and which heavy libraries the import loaded. Then ``scm-calib
serve`` (temporary SQLite database, two local workers) is started ``--repeats`` times: the
median time until ``/health/ready`` answers 200 (database migrated, pool processes warmed).
With ``--baseline REF`` the same runs are made on a git worktree of REF in the same session,
alternating, so both share the machine's noise.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from bench_upload import start_server
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent

ENTRIES = {
    "API (services.api.main)": "services.api.main",
    "worker (worker.runtime)": "worker.runtime",
    "CLI calibrate": "services.cli.calibrate",
    "figure process": "services.api.dashboard.study_figures; services.plots.posterior",
}
HEAVY = ("matplotlib", "scipy.stats", "scipy.signal", "scipy.spatial", "scipy.special", "numba")

_PROBE = """
import importlib, sys, time
t0 = time.perf_counter()
for m in sys.argv[1].split("; "):
    importlib.import_module(m)
print(time.perf_counter() - t0, ", ".join(h for h in sys.argv[2].split() if h in sys.modules))
"""


def import_time(tree: Path, modules: str) -> tuple[float, str]:
    """(wall seconds, heavy libraries loaded) of importing ``modules`` in a fresh process."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, modules, " ".join(HEAVY)],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split(maxsplit=1)
    return float(out[0]), (out[1].strip() if len(out) > 1 else "")


@contextlib.contextmanager
def checkouts(baseline: str | None) -> Iterator[dict[str, Path]]:
    """The trees a benchmark compares: {label: path}, a git worktree of ``baseline`` (removed
    afterwards) first when one is given, then this checkout."""
    if not baseline:
        yield {"this checkout": ROOT}
        return
    tree = Path(tempfile.mkdtemp(prefix="bench-trees-")) / "baseline"
    subprocess.run(
        ["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(tree), baseline],
        check=True,
    )
    try:
        yield {baseline: tree, "this checkout": ROOT}
    finally:
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False
        )


def compile_simulator(tree: Path) -> None:
    """Fill ``tree``'s numba cache (a fresh worktree compiles the simulator once, minutes)."""
    subprocess.run(
        [sys.executable, "-c", "from scm_core.simulator import warm_up; warm_up()"],
        cwd=tree,
        env={**os.environ, "PYTHONPATH": str(tree)},
        check=True,
    )


def serve_ready(tree: Path) -> float:
    """Seconds from starting ``scm-calib serve`` (checkout ``tree``) to a 200 from ready."""
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = str(tree)
    try:
        with tempfile.TemporaryDirectory(prefix="bench-startup-") as d:
            t0 = time.perf_counter()
            proc, _ = start_server(Path(d))
            ready = time.perf_counter() - t0
            proc.terminate()
            proc.wait(30)
    finally:
        if old is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = old
    return ready


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--baseline", help="git ref to compare with (run from a worktree)")
    args = ap.parse_args()
    with checkouts(args.baseline) as trees:
        times: dict[tuple[str, str], list[float]] = {}
        loaded: dict[tuple[str, str], str] = {}
        for tree in trees.values():  # warm-up: bytecode and numba caches, the file cache
            compile_simulator(tree)
            for modules in ENTRIES.values():
                import_time(tree, modules)
        for _ in range(args.repeats):
            for label, tree in trees.items():
                for entry, modules in ENTRIES.items():
                    t, heavy = import_time(tree, modules)
                    times.setdefault((entry, label), []).append(t)
                    loaded[(entry, label)] = heavy
                times.setdefault(("serve: ready", label), []).append(serve_ready(tree))
                loaded[("serve: ready", label)] = ""
    table = Table(title=f"start-up, median of {args.repeats} fresh processes [s]")
    for col in ("process", "checkout", "median s", "min s", "max s", "heavy libraries loaded"):
        table.add_column(
            col, justify="left" if col in ("process", "heavy libraries loaded") else "right"
        )
    for entry in [*ENTRIES, "serve: ready"]:
        for label in trees:
            ts = times[(entry, label)]
            table.add_row(
                entry,
                label,
                f"{statistics.median(ts):.2f}",
                f"{min(ts):.2f}",
                f"{max(ts):.2f}",
                loaded[(entry, label)],
            )
    Console(width=130).print(table)


if __name__ == "__main__":
    main()
