"""``scm-calib worker`` (a Celery worker) and ``scm-calib reaper`` (re-dispatches lost work)."""

from __future__ import annotations

import logging
import signal
import threading

import click

from .common import open_store_or_fail, settings_or_fail

WAIT_DB = click.option(
    "--wait-db",
    type=click.FloatRange(min=0),
    default=30.0,
    show_default=True,
    help="Seconds to wait for the database to answer before giving up.",
)


@click.command("worker")
@click.option("--concurrency", type=int, default=None, help="Processes (default: settings).")
@click.option(
    "--pool",
    type=click.Choice(["prefork", "solo", "threads"]),
    default="prefork",
    help="Celery pool; 'solo' runs batches in this process.",
)
@click.option("--loglevel", default="INFO")
@WAIT_DB
def worker(concurrency: int | None, pool: str, loglevel: str, wait_db: float) -> None:
    """Run a Celery worker that executes TMCMC work batches (needs SCM_CALIB_BROKER_URL).
    It takes no task before the database answers and takes writes."""
    settings = settings_or_fail()
    if not settings.broker_url:
        raise click.UsageError(
            "no broker configured: set SCM_CALIB_BROKER_URL (e.g. redis://127.0.0.1:6379/0); "
            "the embedded mode needs no worker (scm-calib serve runs a local pool)"
        )
    open_store_or_fail(settings, wait_db).close()
    from worker.celery_app import make_celery

    app = make_celery(settings)
    argv = ["worker", f"--loglevel={loglevel}", f"--pool={pool}", "-Q", "scm_calib"]
    argv.append(f"--concurrency={concurrency or settings.worker_concurrency}")
    app.worker_main(argv)


@click.command("reaper")
@click.option(
    "--interval", type=click.FloatRange(min=0.1), default=10.0, show_default=True, help="Seconds."
)
@WAIT_DB
def reaper(interval: float, wait_db: float) -> None:
    """Start studies left queued, re-dispatch lost work batches and advance finished stages
    (distributed mode)."""
    settings = settings_or_fail()
    if not settings.broker_url:
        raise click.UsageError("no broker configured: set SCM_CALIB_BROKER_URL")
    from services.store.engine import safe_url
    from worker.orchestrator import ContextCache, reap_forever
    from worker.runtime import celery_dispatcher

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    store = open_store_or_fail(settings, wait_db)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    click.echo(f"reaper: every {interval:g} s on {safe_url(store.engine.url)}", err=True)
    reap_forever(store, ContextCache(), celery_dispatcher(settings), interval, stop)
