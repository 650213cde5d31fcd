"""The first load of a big study page's figures: fresh figure processes, a 16,000-sample study.

Run: ``python benchmarks/bench_page_figures.py [--repeats 5] [--samples 16000]``. Writes the
calibration of ``tests/web/test_dashboard_scale.py`` (two stages of ``--samples`` samples,
written through the store) into a temporary SQLite database, then ``--repeats`` times starts the
dashboard's figure processes afresh (:class:`~services.api.dashboard.drawing.FigureProcess`, as
the API does when a study page first polls) and asks for the page's charts two at a time in the
page's order (:func:`~services.api.dashboard.study_figures.page_figures`): the wall time from the
start to the first chart and to the last (what the test's first load waits for after its
fragments, the processes' start included). Then each chart made in this process, prepared as
a figure process (:func:`~services.api.dashboard.drawing.prepare_drawing`), in that order with
an empty cache (the reads of a stage's samples shared as in a figure process). Prints the median,
min and max of each [ms].
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path[1:1] = [str(ROOT / "tests" / "api"), str(ROOT / "tests" / "web")]


def write_study(url: str, n: int) -> int:
    """The scale test's big study of ``n`` samples per stage in ``url``: its id."""
    import test_dashboard_scale as scale
    from test_api_support import api_client, upload_file

    scale.N_BIG = n
    with api_client(url) as client:
        ids = [upload_file(client).json()["id"]]
    return scale._big_study(url, ids)


def _page_specs(store: object, study: object) -> list[dict]:
    """The page's charts of the study's last finished stage, in the page's order."""
    from services.api.dashboard.study_figures import page_figures
    from services.api.views import parameter_names

    done = [s.stage_index for s in store.stages.list(study.id) if s.status == "done"]
    return page_figures(parameter_names(study), done[-1])


def cold(url: str, study_id: int, repeats: int) -> dict[str, list[float]]:
    """Seconds from fresh figure processes to the page's first chart and to its last."""
    from services.api.dashboard.drawing import DRAWING_PROCESSES, FigureProcess
    from services.api.dashboard.study_figures import FigureCache, study_figure
    from services.store import Store

    out: dict[str, list[float]] = {}
    with Store.open(url) as store:
        study = store.studies.get(study_id)
        specs = _page_specs(store, study)
        for _ in range(repeats):
            drawer, cache = FigureProcess(url), FigureCache()
            t0 = time.perf_counter()
            drawer.warm()

            def one(spec: dict, drawer=drawer, cache=cache, t0=t0) -> float:
                study_figure(store, study, fmt="json", cache=cache, drawer=drawer, **spec)
                return time.perf_counter() - t0

            with ThreadPoolExecutor(DRAWING_PROCESSES) as pool:  # the page: two at a time
                done = list(pool.map(one, specs))
            drawer.close()
            out.setdefault("first chart (processes started)", []).append(min(done))
            out.setdefault("all charts (processes started)", []).append(max(done))
    return out


def warm(url: str, study_id: int, repeats: int) -> dict[str, list[float]]:
    """Each chart's seconds in this process (a prepared figure process), empty caches."""
    from services.api.dashboard.drawing import prepare_drawing
    from services.api.dashboard.study_figures import FigureCache, study_figure
    from services.store import Store

    prepare_drawing()
    out: dict[str, list[float]] = {}
    with Store.open(url) as store:
        study = store.studies.get(study_id)
        specs = _page_specs(store, study)
        for k in range(repeats + 1):  # the first: warm-up, not counted
            cache = FigureCache()
            total = 0.0
            for spec in specs:
                t0 = time.perf_counter()
                study_figure(store, study, fmt="json", cache=cache, **spec)
                dt = time.perf_counter() - t0
                total += dt
                if k:
                    out.setdefault(spec["name"], []).append(dt)
            if k:
                out.setdefault("sum, one process", []).append(total)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--samples", type=int, default=16_000)
    args = ap.parse_args()
    from test_api_support import fresh_database

    with (
        tempfile.TemporaryDirectory(prefix="bench-page-figures-") as d,
        fresh_database("sqlite", Path(d)) as url,
    ):
        sid = write_study(url, args.samples)
        times = {**cold(url, sid, args.repeats), **warm(url, sid, args.repeats)}
    table = Table(title=f"a {args.samples}-sample study page's charts (json), {args.repeats} runs")
    for col in ("", "median ms", "min ms", "max ms"):
        table.add_column(col, justify="right")
    for label, ts in times.items():
        ms = [1000 * t for t in ts]
        table.add_row(label, f"{statistics.median(ms):.0f}", f"{min(ms):.0f}", f"{max(ms):.0f}")
    Console().print(table)


if __name__ == "__main__":
    main()
