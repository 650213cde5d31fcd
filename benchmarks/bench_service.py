"""Service benchmark: fixed reduced studies on 1 and 2 Celery workers (real PostgreSQL, Redis).

Run: ``python benchmarks/bench_service.py [--workers 1 2] [--repeats 3] [--case FILE ...]``.
Needs PostgreSQL at 127.0.0.1:5432 (trust) and ``redis-server`` on PATH; makes a temporary
database and a throwaway Redis, both removed afterwards. Cases: ``bench_case.toml`` (32 samples
per stage, 5 stages) and ``bench_case_128.toml`` (128 samples per stage, 3 stages), both with
the default (paper) simulator numerics. Reports the study's wall time (start to finish in the
database), the simulator time summed over all batches, and the share of worker time spent
outside the simulator, 1 - simulator time / (workers x wall time), split into: the rest of the
batch computation, claiming and storing batches, start-up, stage transitions (reduce, plan,
dispatch, pick-up) and idle time at stage barriers (with the pick-up gaps between batches).
The barrier share falls as 1 / (samples per stage): a worker waits for about half of the
last chain still running. Two more columns separate what the service adds from what
synchronous TMCMC stages cost by themselves: "TMCMC idle (no service)" is the idle share of
the same batches scheduled in order on the same workers with no service at all (each batch
taking exactly its simulator time), and "service share" is 1 - that ideal wall time / the
measured wall time: the wall time added by queueing, database, serialisation and dispatch.
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
CASES = [ROOT / "benchmarks" / "bench_case.toml", ROOT / "benchmarks" / "bench_case_128.toml"]
LOG = ROOT / "examples" / "wf34_s020.csv"
ADMIN = "postgresql://postgres@127.0.0.1:5432/postgres"
SHARES = (
    "overhead",
    "in_batch",
    "bookkeeping",
    "startup",
    "transitions",
    "barrier",
    "service",
    "tmcmc_idle",
)


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
    from services.studies import calibration_spec, create_and_start
    from worker.celery_app import make_celery
    from worker.dispatch import CeleryDispatcher
    from worker.orchestrator import wait_for_study

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
        spec = calibration_spec(store, Settings(), case, [rec.id])
        study_id = create_and_start(store, spec, dispatcher)
        final = wait_for_study(store, study_id, timeout=1800, poll=0.2)
        assert final.status in ("completed", "stalled"), final.error
        row = breakdown(store, final, n_workers)
        store.close()
        return row
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


def breakdown(store, study, n_workers: int) -> dict[str, float]:
    """Where the workers' time went (seconds of worker time, n_workers x wall in all).

    simulator: inside the model function; in_batch: the rest of a batch's computation (plan
    fetch, chain bookkeeping); bookkeeping: lease to stored result minus computation (claim,
    encode, store); startup: study start to first lease; transitions: from the last result
    of a stage to the first lease of the next (reduce, plan, dispatch, pick-up), all workers;
    barrier: the rest, i.e. workers idle while others finish a stage's last batches.
    """
    wall = (study.finished_at - study.started_at).total_seconds()
    done = {
        (p["stage"], p["batch"]): p
        for p in (
            e.payload for e in store.events.list(study.id, kinds=["batch_done"], limit=100000)
        )
    }
    batches = [b for b in store.batches.list(study.id) if b.status == "done"]
    model = sum(p["model_s"] for p in done.values())
    compute = sum(p["compute_s"] for p in done.values())
    held = sum((b.finished_at - b.leased_at).total_seconds() for b in batches)
    by_stage: dict[int, list] = {}
    for b in batches:
        by_stage.setdefault(b.key.stage_index, []).append(b)
    stages = sorted(by_stage)
    first = min(b.leased_at for b in by_stage[stages[0]])
    startup = (first - study.started_at).total_seconds()
    transitions = sum(
        (
            min(b.leased_at for b in by_stage[k]) - max(b.finished_at for b in by_stage[k - 1])
        ).total_seconds()
        for k in stages[1:]
    )
    tail = (study.finished_at - max(b.finished_at for b in by_stage[stages[-1]])).total_seconds()
    # the same batches on n_workers with no service at all (each batch takes its simulator
    # time, workers take batches in order, stages one after another): what synchronous TMCMC
    # stages cost by themselves; the service adds the rest of the wall time
    ideal = 0.0
    for k in stages:
        free = [0.0] * n_workers
        for b in sorted(by_stage[k], key=lambda b: b.key.batch_index):
            w = free.index(min(free))
            free[w] += done[(k, b.key.batch_index)]["model_s"]
        ideal += max(free)
    total = n_workers * wall
    fixed = n_workers * (startup + transitions + tail)
    return {
        "wall": wall,
        "model": model,
        "compute": compute,
        "runs": study.model_runs,
        "batches": len(batches),
        "overhead": 1.0 - model / total,
        "in_batch": (compute - model) / total,
        "bookkeeping": (held - compute) / total,
        "startup": n_workers * startup / total,
        "transitions": n_workers * (transitions + tail) / total,
        "barrier": (total - held - fixed) / total,
        "ideal_wall": ideal,
        "tmcmc_idle": 1.0 - model / (n_workers * ideal),
        "service": 1.0 - ideal / wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--case", type=Path, nargs="+", default=CASES, help="study case files (TOML)")
    ap.add_argument("--verbose", action="store_true", help="print every run's breakdown")
    args = ap.parse_args()
    for case in args.case:
        table = Table(title=f"{case.name} on Celery workers (median of {args.repeats})")
        for col in ("workers", "wall [s]", "simulator [s]", "model runs", "batches",
                    "outside simulator", "in batch", "claim/store", "startup",
                    "stage transitions", "idle at barriers", "service share",
                    "TMCMC idle (no service)"):  # fmt: skip
            table.add_column(col, justify="right")
        with tempfile.TemporaryDirectory() as tmp:
            for n in args.workers:
                rows = [run_once(n, Path(tmp), case) for _ in range(args.repeats)]
                med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
                pct = [f"{100 * med[k]:.1f} %" for k in SHARES]
                table.add_row(
                    str(n),
                    f"{med['wall']:.2f}",
                    f"{med['model']:.2f}",
                    f"{med['runs']:.0f}",
                    f"{med['batches']:.0f}",
                    *pct,
                )
                if args.verbose:
                    for r in rows:
                        print(case.name, n, {k: round(v, 4) for k, v in r.items()})
        Console(width=200).print(table)


if __name__ == "__main__":
    main()
