"""What a connection per transaction costs the API server's SQLite store (issue 73).

Run: ``python benchmarks/bench_store_connections.py [--n 2000] [--repeats 5]``.

The API server's store opens a SQLite connection per transaction and closes it at the end
(``Store.open(..., keep_connections=False)``), so that it holds no map of the database's
shared-memory index between transactions (a SIGBUS when the filesystem stops taking writes).
This prints, for pooled connections (every other process) and one per transaction (the API
server), the median over ``--repeats`` runs of the time of one read transaction (a study's
record, what a status poll reads) and one write transaction (a heartbeat beat, what
readiness commits), with another process holding the database open as the server's pool
processes do.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from services.store import Store, upgrade  # noqa: E402


def _per_call(fn, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000, help="transactions per run")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.db"
        url = f"sqlite:///{path}"
        upgrade(url)
        holder = subprocess.Popen(
            [
                sys.executable,
                "-c",
                "import sqlite3, sys; c = sqlite3.connect(sys.argv[1]); "
                "c.execute('SELECT 1 FROM sqlite_master').fetchall(); sys.stdin.read()",
                str(path),
            ],
            stdin=subprocess.PIPE,
        )
        try:
            rows = {}
            for keep in (True, False):
                store = Store.open(url, keep_connections=keep)
                store.check_writable("bench")
                reads, writes = [], []
                for _ in range(args.repeats):  # alternate-free: each mode in one block
                    reads.append(_per_call(lambda s=store: s.studies.list(), args.n))
                    writes.append(_per_call(lambda s=store: s.check_writable("bench"), args.n))
                store.close()
                rows[keep] = (statistics.median(reads), statistics.median(writes))
        finally:
            holder.stdin.close()
            holder.wait()
    table = Table(title=f"one SQLite transaction, median of {args.repeats} x {args.n} (us)")
    for col in ("connections", "read (list studies)", "write (heartbeat)"):
        table.add_column(col, justify="left" if col == "connections" else "right")
    for keep, (r, w) in rows.items():
        label = "pooled (workers, CLI)" if keep else "one per transaction (API server)"
        table.add_row(label, f"{r:.0f}", f"{w:.0f}")
    Console(width=100).print(table)


if __name__ == "__main__":
    main()
