"""Upload benchmark: parsing a large SWT log, and uploading it to a real embedded server.

Run: ``python benchmarks/bench_upload.py [--mb 15 60] [--repeats 3] [--baseline REF]``.

Two tables, medians of ``--repeats`` runs:

* **parse**: ``load_dataset(path, keep_series=False)`` in a fresh process per run: wall time and
  peak RSS rise (``VmHWM`` after minus ``VmRSS`` before, the peak reset after the imports
  through ``/proc/self/clear_refs``). With ``--baseline REF`` the same
  is run on a git worktree of REF (e.g. the commit before chunked parsing) in the same session,
  so before and after share the machine's noise.
* **server**: ``scm-calib serve`` (temporary SQLite database, 2 pool processes) on 127.0.0.1:
  the first upload of the log (201) and an identical re-upload (200), wall time at the client
  and the API process's peak RSS rise (``VmHWM`` after minus ``VmRSS`` before, peak reset
  through ``/proc/PID/clear_refs`` before each upload).

The logs are synthetic (1 kHz, t, F, T, z at 17 significant digits, noise around steady
values), written by ``scm_core.signals.write_log``.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
TOKEN = "bench-token"
BYTES_PER_ROW = 75.6  # measured for this generator

PARSE_SNIPPET = """
import sys, time
from pathlib import Path
from scm_core.signals import load_dataset

def status(key):
    lines = Path("/proc/self/status").read_text().splitlines()
    return next(int(x.split()[1]) for x in lines if x.startswith(key + ":"))

Path("/proc/self/clear_refs").write_text("5")  # peak := current, after the imports
before = status("VmRSS")
t0 = time.perf_counter()
load_dataset(sys.argv[1], keep_series=False)
dt = time.perf_counter() - t0
print(dt, (status("VmHWM") - before) / 1024.0)
"""


def make_log(path: Path, megabytes: float) -> Path:
    import numpy as np

    from scm_core.signals import write_log

    n = int(megabytes * 1e6 / BYTES_PER_ROW)
    rng = np.random.default_rng(1)
    t = np.arange(n) / 1000.0
    write_log(
        path,
        t,
        20 + rng.normal(0, 1, n),
        5 + rng.normal(0, 0.2, n),
        0.012 + rng.normal(0, 1e-4, n),
        {"W": 315.0, "slip": 0.2, "omega": 0.5, "R": 0.25, "b": 0.2},
        sidecar=False,
    )
    return path


def parse_once(log: Path, pythonpath: Path) -> tuple[float, float]:
    env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    out = subprocess.run(
        [sys.executable, "-c", PARSE_SNIPPET, str(log)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=pythonpath,
    ).stdout.split()
    return float(out[0]), float(out[1])


def _status_mb(pid: int, key: str) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024.0
    raise KeyError(key)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(tmp: Path) -> tuple[subprocess.Popen, str]:
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("SCM_CALIB_")}
    env.update(SCM_CALIB_DATA_DIR=str(tmp / "data"), SCM_CALIB_API_TOKENS=TOKEN)
    proc = subprocess.Popen(
        [sys.executable, "-m", "services.cli", "serve", "--port", str(port), "--workers", "2"],
        env=env,
        cwd=tmp,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            if httpx.get(base + "/health/ready", timeout=2).status_code == 200:
                return proc, base
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    proc.kill()
    raise RuntimeError("serve did not come up")


def upload_once(base: str, pid: int, log: Path) -> tuple[int, float, float]:
    Path(f"/proc/{pid}/clear_refs").write_text("5")  # reset the peak RSS
    before = _status_mb(pid, "VmRSS")
    with log.open("rb") as f:
        t0 = time.perf_counter()
        r = httpx.post(
            base + "/datasets",
            files={"file": (log.name, f, "text/csv")},
            headers={"Authorization": f"Bearer {TOKEN}"},
            timeout=300,
        )
        dt = time.perf_counter() - t0
    return r.status_code, dt, _status_mb(pid, "VmHWM") - before


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mb", type=float, nargs="+", default=[15.0, 60.0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--baseline", help="git ref to compare parsing with (a worktree)")
    args = parser.parse_args()
    console = Console()
    with tempfile.TemporaryDirectory(prefix="bench-upload-") as tmpdir:
        tmp = Path(tmpdir)
        logs = {mb: make_log(tmp / f"log_{mb:g}mb.csv", mb) for mb in args.mb}
        trees = {"this tree": ROOT}
        if args.baseline:
            tree = tmp / "baseline"
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(tree),
                 args.baseline],
                check=True,
            )  # fmt: skip
            trees[args.baseline] = tree
        try:
            table = Table(title=f"parse (median of {args.repeats} fresh processes)")
            for col in ("code", "file MB", "rows", "time s", "peak RSS rise MB", "rise / size"):
                table.add_column(col, justify="right")
            for log in logs.values():
                size = log.stat().st_size / 1e6
                rows = sum(1 for _ in log.open("rb"))
                for label, tree in trees.items():
                    runs = [parse_once(log, tree) for _ in range(args.repeats)]
                    dt = statistics.median(r[0] for r in runs)
                    rise = statistics.median(r[1] for r in runs)
                    table.add_row(
                        label, f"{size:.1f}", f"{rows}", f"{dt:.2f}", f"{rise:.0f}",
                        f"{rise * 1.048576 / size:.2f}",
                    )  # fmt: skip
            console.print(table)
        finally:
            if args.baseline:
                tree = str(tmp / "baseline")
                subprocess.run(
                    ["git", "-C", str(ROOT), "worktree", "remove", "--force", tree], check=False
                )

        table = Table(title=f"server upload (embedded SQLite, median of {args.repeats} servers)")
        for col in ("file MB", "upload", "status", "time s", "API peak RSS rise MB", "rise / size"):
            table.add_column(col, justify="right")
        for mb, log in logs.items():
            size = log.stat().st_size / 1e6
            results: dict[str, list[tuple[int, float, float]]] = {"first": [], "identical": []}
            for k in range(args.repeats):
                run_dir = tmp / f"server_{mb:g}_{k}"
                run_dir.mkdir()
                proc, base = start_server(run_dir)
                try:
                    results["first"].append(upload_once(base, proc.pid, log))
                    results["identical"].append(upload_once(base, proc.pid, log))
                finally:
                    proc.send_signal(signal.SIGINT)
                    proc.wait(timeout=60)
            for kind, runs in results.items():
                table.add_row(
                    f"{size:.1f}",
                    kind,
                    "/".join(sorted({str(r[0]) for r in runs})),
                    f"{statistics.median(r[1] for r in runs):.2f}",
                    f"{statistics.median(r[2] for r in runs):.0f}",
                    f"{statistics.median(r[2] for r in runs) * 1.048576 / size:.2f}",
                )
        console.print(table)


if __name__ == "__main__":
    main()
