"""Service benchmark: a fixed reduced study on 1 and 2 Celery workers (real PostgreSQL and Redis).

Run: ``python benchmarks/bench_service.py [--workers 1 2] [--repeats 3]``. Needs PostgreSQL at
127.0.0.1:5432 (trust) and ``redis-server`` on PATH; makes a temporary database and a throwaway
Redis, both removed afterwards. Reports the study's wall time (start to finish in the database),
the simulator time summed over all batches, and the share of worker time spent outside the
simulator: 1 - simulator time / (workers x wall time). That share holds queueing, database and
serialisation, and the idle time of workers at stage barriers.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import psycopg
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
CASE = ROOT / "benchmarks" / "bench_case.toml"
LOG = ROOT / "examples" / "wf34_s020.csv"
ADMIN = "postgresql://postgres@127.0.0.1:5432/postgres"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_once(n_workers: int, tmp: Path, case_file: Path) -> dict[str, float]:
    from scm_core.calibration import load_case
    from scm_core.signals import load_log
    from services.config import Settings
    from services.store import Store
    from services.store.migrate import upgrade
    from worker.celery_app import make_celery
    from worker.dispatch import CeleryDispatcher
    from worker.orchestrator import submit_study, wait_for_study

    name = f"scm_calib_bench_{uuid.uuid4().hex[:8]}"
    with psycopg.connect(ADMIN, autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    url = f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"
    port = free_port()
    redis = subprocess.Popen(
        ["redis-server", "--port", str(port), "--bind", "127.0.0.1", "--save", ""],
        stdout=subprocess.DEVNULL,
    )
    broker = f"redis://127.0.0.1:{port}/0"
    procs = []
    try:
        upgrade(url)
        env = dict(os.environ, SCM_CALIB_DATABASE_URL=url, SCM_CALIB_BROKER_URL=broker)
        env["NUMBA_NUM_THREADS"] = "1"
        for i in range(n_workers):
            log = open(tmp / f"w{n_workers}_{i}.log", "w")  # noqa: SIM115
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-m", "services.cli", "worker", "--pool", "solo"],
                    env=env,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                )
            )
        time.sleep(5.0)  # workers up (imports, numba cache)
        store = Store.open(url)
        case = load_case(case_file)
        raw = LOG.read_bytes()
        meta = json.loads(LOG.with_suffix(".json").read_text())
        rec, _ = store.datasets.add(load_log(raw, metadata=meta), raw, meta=meta)
        dispatcher = CeleryDispatcher(make_celery(Settings(database_url=url, broker_url=broker)))
        study = submit_study(store, case, [rec.id], dispatcher)
        final = wait_for_study(store, study.id, timeout=1800, poll=0.2)
        assert final.status in ("completed", "stalled"), final.error
        wall = (final.finished_at - final.started_at).total_seconds()
        done = [e.payload for e in store.events.list(study.id, kinds=["batch_done"], limit=100000)]
        model = sum(p["model_s"] for p in done)
        compute = sum(p["compute_s"] for p in done)
        store.close()
        return {
            "wall": wall,
            "model": model,
            "compute": compute,
            "runs": final.model_runs,
            "overhead": 1.0 - model / (n_workers * wall),
        }
    finally:
        for p in procs:
            p.kill()
            p.wait()
        redis.kill()
        redis.wait()
        with psycopg.connect(ADMIN, autocommit=True) as conn:
            conn.execute(
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = %s",
                (name,),
            )
            conn.execute(f'DROP DATABASE IF EXISTS "{name}"')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--case", type=Path, default=CASE, help="study case file (TOML)")
    args = ap.parse_args()
    table = Table(title=f"{args.case.name} on Celery workers (median of {args.repeats})")
    for col in ("workers", "wall [s]", "simulator [s]", "batch compute [s]", "model runs",
                "outside simulator"):  # fmt: skip
        table.add_column(col, justify="right")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.workers:
            rows = [run_once(n, Path(tmp), args.case) for _ in range(args.repeats)]
            med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
            table.add_row(
                str(n),
                f"{med['wall']:.2f}",
                f"{med['model']:.2f}",
                f"{med['compute']:.2f}",
                f"{med['runs']:.0f}",
                f"{100 * med['overhead']:.1f} %",
            )
    Console().print(table)


if __name__ == "__main__":
    main()
