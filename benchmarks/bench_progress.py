"""How a watcher learns of a running study's changes: polling with ETags against server-sent events.

Run: ``python benchmarks/bench_progress.py [--repeats 3] [--poll 1.0]``. Each repeat serves a
fresh embedded instance (SQLite, two local workers), runs one small calibration (a few stages,
each of a few seconds) and watches it three ways at once:

* **reference**: ``GET /studies/{id}`` every 0.05 s, which dates each new version of the study
  (the lag of the others is measured against it);
* **polling** (what the dashboard does): ``GET /studies/{id}`` every ``--poll`` seconds with
  ``If-None-Match``, a 304 while nothing changed;
* **stream**: ``GET /studies/{id}/stream`` (server-sent events, read by the Python client's
  ``watch``).

Prints per way and repeat: requests made, bytes received, how many of the study's versions it
saw, and the median and largest lag behind the reference (ms); then the medians over the
repeats. The page's own numbers (two fragments polled per open study page) are twice the
polling column's requests.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx
from bench_upload import TOKEN, start_server  # the same served instance
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
AUTH = {"Authorization": f"Bearer {TOKEN}"}
LOGS = ("wf34_s020.csv", "wf34_s050.csv")
CASE = {
    "name": "progress",
    "seed": 13,
    "likelihood": "gaussian",
    "parameters": {
        "phi": {"dist": "uniform", "lower": 20.0, "upper": 35.0, "unit": "deg"},
        "n": {"dist": "uniform", "lower": 0.9, "upper": 1.3},
    },
    "nominal": {"k_c": 0.0, "sigma_F": 3.0, "sigma_T": 0.3, "sigma_z": 0.0005},
    "simulator": {"duration": 8.0, "dx": 0.01, "dt": 0.04, "offset_F": 3.0, "offset_T": 3.0},
    "sampler": {"n_samples": 200, "moves": "leader", "max_stages": 10},
}


class Watch:
    """What one way of watching saw: version -> first seen (monotonic s), requests, bytes."""

    def __init__(self) -> None:
        self.seen: dict[int, float] = {}
        self.requests = 0
        self.bytes = 0

    def saw(self, version: int) -> None:
        self.seen.setdefault(version, time.monotonic())


def _poll(base: str, sid: int, every: float, watch: Watch, stop: threading.Event) -> None:
    etag = None
    with httpx.Client(base_url=base, headers=AUTH, timeout=30) as client:
        while not stop.is_set():
            headers = {"If-None-Match": etag} if etag else {}
            r = client.get(f"/studies/{sid}", headers=headers)
            watch.requests += 1
            watch.bytes += len(r.content)
            if r.status_code == 200:
                etag = r.headers.get("etag")
                watch.saw(r.json()["version"])
                if r.json()["status"] not in ("queued", "running"):
                    return
            stop.wait(every)


def _stream(base: str, sid: int, watch: Watch) -> None:
    from services.client import SCMCalibClient

    with SCMCalibClient(base, token=TOKEN) as api:
        watch.requests += 1
        for study in api.watch(sid):
            watch.bytes += len(str(study))  # the event's JSON (about its wire size)
            watch.saw(study["version"])


def one_run(poll_every: float) -> dict[str, dict[str, float]]:
    from services.client import SCMCalibClient

    with tempfile.TemporaryDirectory(prefix="bench-progress-") as d:
        proc, base = start_server(Path(d))
        try:
            with SCMCalibClient(base, token=TOKEN) as api:
                ids = [api.upload_log(ROOT / "examples" / f)["id"] for f in LOGS]
                sid = api.create_study(case=CASE, dataset_ids=ids, name="progress")["id"]
            ways = {"reference": Watch(), "polling": Watch(), "stream": Watch()}
            stop = threading.Event()
            threads = [
                threading.Thread(target=_poll, args=(base, sid, 0.05, ways["reference"], stop)),
                threading.Thread(target=_poll, args=(base, sid, poll_every, ways["polling"], stop)),
                threading.Thread(target=_stream, args=(base, sid, ways["stream"])),
            ]
            t0 = time.monotonic()
            for t in threads:
                t.start()
            for t in threads:
                t.join(1800)
            stop.set()
            wall = time.monotonic() - t0
        finally:
            proc.terminate()
            proc.wait(30)
    ref = ways["reference"].seen
    out = {}
    for name, w in ways.items():
        lags = [1000.0 * (t - ref[v]) for v, t in w.seen.items() if v in ref]
        out[name] = {
            "requests": w.requests,
            "per_minute": 60.0 * w.requests / wall,
            "kB": w.bytes / 1024,
            "versions": len(w.seen),
            "lag_median": statistics.median(lags) if lags else float("nan"),
            "lag_max": max(lags) if lags else float("nan"),
            "wall": wall,
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--poll", type=float, default=1.0, help="polling period [s] (the page's: 1)")
    args = ap.parse_args()
    console = Console()
    runs = []
    table = Table(title=f"watching a running study (polling every {args.poll:g} s)")
    for col in (
        "run",
        "way",
        "requests",
        "per minute",
        "kB",
        "versions seen",
        "lag median ms",
        "lag max ms",
        "study wall s",
    ):
        table.add_column(col, justify="right")
    for k in range(args.repeats):
        run = one_run(args.poll)
        runs.append(run)
        for name, r in run.items():
            table.add_row(
                str(k + 1),
                name,
                f"{r['requests']}",
                f"{r['per_minute']:.0f}",
                f"{r['kB']:.0f}",
                f"{r['versions']}",
                f"{r['lag_median']:.0f}",
                f"{r['lag_max']:.0f}",
                f"{r['wall']:.0f}",
            )
    for name in runs[0]:
        med = {key: statistics.median(r[name][key] for r in runs) for key in runs[0][name]}
        table.add_row(
            "median",
            name,
            f"{med['requests']:.0f}",
            f"{med['per_minute']:.0f}",
            f"{med['kB']:.0f}",
            f"{med['versions']:.0f}",
            f"{med['lag_median']:.0f}",
            f"{med['lag_max']:.0f}",
            f"{med['wall']:.0f}",
        )
    console.print(table)


if __name__ == "__main__":
    main()
