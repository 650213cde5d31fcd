"""``scm-calib worker`` (a Celery worker) and ``scm-calib reaper`` (re-dispatches lost work)."""

from __future__ import annotations

import logging
import signal
import threading

import click

from services.config import get_settings


@click.command("worker")
@click.option("--concurrency", type=int, default=None, help="Processes (default: settings).")
@click.option(
    "--pool",
    type=click.Choice(["prefork", "solo", "threads"]),
    default="prefork",
    help="Celery pool; 'solo' runs batches in this process.",
)
@click.option("--loglevel", default="INFO")
def worker(concurrency: int | None, pool: str, loglevel: str) -> None:
    """Run a Celery worker that executes TMCMC work batches (needs SCM_CALIB_BROKER_URL)."""
    settings = get_settings()
    if not settings.broker_url:
        raise click.UsageError(
            "no broker configured: set SCM_CALIB_BROKER_URL (e.g. redis://127.0.0.1:6379/0); "
            "the embedded mode needs no worker (scm-calib serve runs a local pool)"
        )
    from worker.celery_app import make_celery

    app = make_celery(settings)
    argv = ["worker", f"--loglevel={loglevel}", f"--pool={pool}", "-Q", "scm_calib"]
    argv.append(f"--concurrency={concurrency or settings.worker_concurrency}")
    app.worker_main(argv)


@click.command("reaper")
@click.option("--interval", type=float, default=10.0, show_default=True, help="Seconds.")
def reaper(interval: float) -> None:
    """Re-dispatch lost work batches and advance finished stages (distributed mode)."""
    settings = get_settings()
    if not settings.broker_url:
        raise click.UsageError("no broker configured: set SCM_CALIB_BROKER_URL")
    from services.store import Store
    from worker.orchestrator import ContextCache, reap_forever
    from worker.runtime import celery_dispatcher

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    store = Store.from_settings(settings)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    click.echo(f"reaper: every {interval:g} s on {store.engine.url!s}", err=True)
    reap_forever(store, ContextCache(), celery_dispatcher(settings), interval, stop)
