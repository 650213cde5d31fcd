"""What each of a study page's figures costs to make, cold (no cache), per stage.

Run: ``python benchmarks/bench_figures.py [--repeats 5] [--fmt json svg]``. Serves a fresh
embedded instance (SQLite, two local workers) once, runs bench_progress's small calibration to
its end, stops the server, then makes the last finished stage's page figures
(:func:`services.api.dashboard.study_figures.page_figures`) in this process with an empty cache,
``--repeats`` times per format, and prints the median and spread of each figure's wall time
[ms] and size [kB], their sum, and the makespan of the two figure processes' longest-first
schedule (what the page waits for after a stage ends, on top of its poll). ``json`` is the
chart's data the page draws (issue 45), ``svg``/``png`` the matplotlib drawing of the same
chart (the downloads; what the page showed before). The simulator is compiled and matplotlib
warmed before the first repeat, as the dashboard's figure processes do
(:func:`~services.api.dashboard.drawing.prepare_drawing`).
"""

from __future__ import annotations

import argparse
import heapq
import statistics
import sys
import tempfile
import time
from pathlib import Path

from bench_progress import AUTH, CASE, LOGS, TOKEN  # the same small calibration
from bench_upload import start_server
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def run_study(tmp: Path) -> tuple[str, int]:
    """Serve, run the calibration to its end, stop; (database URL, study id)."""
    import httpx

    from services.client import SCMCalibClient

    proc, base = start_server(tmp)
    try:
        with SCMCalibClient(base, token=TOKEN) as api:
            ids = [api.upload_log(ROOT / "examples" / f)["id"] for f in LOGS]
            sid = api.create_study(case=CASE, dataset_ids=ids, name="figures")["id"]
            deadline = time.monotonic() + 1800
            while time.monotonic() < deadline:
                status = httpx.get(f"{base}/studies/{sid}", headers=AUTH).json()["status"]
                if status not in ("queued", "running"):
                    break
                time.sleep(0.5)
    finally:
        proc.terminate()
        proc.wait(30)
    return f"sqlite:///{(tmp / 'data' / 'scm-calib.db').as_posix()}", sid


def makespan(seconds: list[float], processes: int) -> float:
    """Longest-first list schedule of ``seconds`` on ``processes`` (the warmer's)."""
    loads = [0.0] * processes
    for s in sorted(seconds, reverse=True):
        heapq.heappush(loads, heapq.heappop(loads) + s)
    return max(loads)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fmt", nargs="+", default=["json", "svg"], choices=("json", "svg", "png"))
    args = ap.parse_args()

    from services.api.dashboard.drawing import prepare_drawing
    from services.api.dashboard.study_figures import page_figures
    from services.api.views import parameter_names
    from services.store import Store

    with tempfile.TemporaryDirectory(prefix="bench-figures-") as d:
        url, sid = run_study(Path(d))
        store = Store.open(url)
        study = store.studies.get(sid)
        done = [s.stage_index for s in store.stages.list(sid) if s.status == "done"]
        specs = page_figures(parameter_names(study), done[-1])
        prepare_drawing()  # as a figure process
        results = {fmt: measure(store, study, specs, fmt, args.repeats) for fmt in args.fmt}
        store.close()
    for fmt, (times, sizes) in results.items():
        report(times, sizes, f"page figures of the last stage ({done[-1]}), cold, {fmt}")


def measure(
    store: object, study: object, specs: list[dict], fmt: str, repeats: int
) -> tuple[dict[str, list[float]], dict[str, float]]:
    """Each figure's wall times [s] over ``repeats`` cold makes (after one not counted) and
    its size [kB]."""
    from services.api.dashboard.study_figures import FigureCache, study_figure

    times: dict[str, list[float]] = {}
    sizes: dict[str, float] = {}
    for k in range(repeats + 1):  # the first: warm-up, not counted
        cache = FigureCache()
        for spec in specs:
            label = spec["name"] + (f" {'/'.join(spec['pair'])}" if "pair" in spec else "")
            t0 = time.perf_counter()
            body = study_figure(store, study, fmt=fmt, cache=cache, **spec)
            if k:
                times.setdefault(label, []).append(time.perf_counter() - t0)
            sizes[label] = len(body) / 1024
    return times, sizes


def report(times: dict[str, list[float]], sizes: dict[str, float], title: str) -> None:
    from services.api.dashboard.drawing import DRAWING_PROCESSES

    table = Table(title=title)
    for col in ("figure", "median ms", "min ms", "max ms", "kB"):
        table.add_column(col, justify="right")
    medians = {}
    for label, ts in times.items():
        medians[label] = statistics.median(ts)
        table.add_row(
            label,
            f"{1000 * medians[label]:.0f}",
            f"{1000 * min(ts):.0f}",
            f"{1000 * max(ts):.0f}",
            f"{sizes[label]:.0f}",
        )
    total = sum(medians.values())
    table.add_row("sum", f"{1000 * total:.0f}", "", "", f"{sum(sizes.values()):.0f}")
    span = makespan(list(medians.values()), DRAWING_PROCESSES)
    table.add_row(f"makespan on {DRAWING_PROCESSES} processes", f"{1000 * span:.0f}", "", "", "")
    Console().print(table)


if __name__ == "__main__":
    main()
