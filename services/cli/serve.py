"""``scm-calib serve``: the REST API (uvicorn), embedded by default.

Embedded (the default): the SQLite file of the settings (``scm-calib-data/scm-calib.db``) and a
local process pool that runs every study; the database is created or migrated on start, so a
fresh machine needs no other step. Distributed: when ``SCM_CALIB_BROKER_URL`` is set
(environment, ``.env`` or the config file), the API only dispatches work to Celery workers
(``scm-calib worker``; run ``scm-calib reaper`` too); a database other than SQLite must already
be at the code's schema revision (``scm-calib db upgrade``).
"""

from __future__ import annotations

import contextlib
import gc

import click


def _prepare_database(url: str) -> None:
    """Migrate an embedded SQLite database; refuse any other database not at head."""
    from sqlalchemy.engine import make_url

    from services.store import SchemaVersionError, Store, migrate
    from services.store.engine import safe_url

    try:
        backend = make_url(url).get_backend_name()
    except Exception as exc:
        raise click.ClickException(f"database URL {url!r}: {exc}") from None
    try:
        if backend == "sqlite":
            before = migrate.current_revision(url)
            migrate.upgrade(url)
            after = migrate.current_revision(url)
            if before != after:
                click.echo(
                    f"database {safe_url(url)}: migrated {before or 'base'} -> {after}", err=True
                )
            return
        Store.open(url).close()
    except SchemaVersionError as exc:
        raise click.ClickException(str(exc)) from None
    except Exception as exc:
        msg = " ".join(str(exc).split())
        raise click.ClickException(
            f"cannot open the database {safe_url(url)}: {type(exc).__name__}: {msg}"
        ) from None


@click.command("serve")
@click.option("--host", default="127.0.0.1", show_default=True, help="Interface to listen on.")
@click.option(
    "--port", type=click.IntRange(1, 65535), default=8000, show_default=True, help="TCP port."
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Processes of the local pool (embedded mode) [default: SCM_CALIB_WORKER_CONCURRENCY "
    "or the CPU count].",
)
@click.option(
    "--no-local-workers",
    is_flag=True,
    help="Embedded mode: accept and record studies but run none here.",
)
@click.option(
    "--log-level",
    type=click.Choice(["critical", "error", "warning", "info", "debug"]),
    default="info",
    show_default=True,
)
def serve(host: str, port: int, workers: int | None, no_local_workers: bool, log_level: str):
    """Run the REST API (OpenAPI docs at /docs): embedded by default (SQLite file + local
    process pool); distributed when SCM_CALIB_BROKER_URL is set."""
    from services.config import get_settings

    try:
        settings = get_settings()
    except Exception as exc:
        raise click.ClickException(f"settings: {' '.join(str(exc).split())}") from None
    distributed = not settings.embedded
    if workers is not None:
        settings = settings.model_copy(update={"worker_concurrency": workers})
    _prepare_database(settings.database_url)

    import uvicorn

    from services.api import create_app
    from services.store.engine import safe_url

    if distributed:
        mode = f"distributed: work goes to Celery at {safe_url(settings.broker_url or '')}"
        if workers is not None:
            click.echo("note: --workers applies to the embedded mode; ignored", err=True)
    elif no_local_workers:
        mode = "embedded, no local workers: studies are recorded but not run here"
    else:
        mode = f"embedded: {settings.worker_concurrency} local worker process(es)"
    click.echo(f"scm-calib serve: {mode}; database {safe_url(settings.database_url)}", err=True)
    if not settings.api_tokens:
        click.echo(
            "warning: no API tokens configured (SCM_CALIB_API_TOKENS): uploads and submissions "
            "are refused; make one with `python -m services.config new-token`",
            err=True,
        )
    if not no_local_workers and not distributed:
        from scm_core.simulator.jit_cache import kernel_is_cached

        if kernel_is_cached() is False:
            click.echo(
                "compiling the simulator in the worker processes, first run only (about 20 "
                "s); /health/ready answers 503 until they are ready",
                err=True,
            )
    app = create_app(settings, start_local_runtime=not no_local_workers)
    if settings.dashboard:
        click.echo(f"dashboard: http://{host}:{port}/", err=True)
    # what is loaded now (FastAPI, SQLAlchemy, numba: about 170,000 objects) lives as long
    # as the server: frozen, the collector's full passes no longer walk it; one came every
    # few reads of a large stage's samples (a page's results, a comparison) and took 0.4-0.5 s
    # on a busy core (figure processes: services.api.dashboard.drawing.prepare_drawing)
    gc.collect()
    gc.freeze()
    # uvicorn 0.29-0.30 re-raise the Ctrl-C they already handled: a clean stop all the same
    with contextlib.suppress(KeyboardInterrupt):
        uvicorn.run(app, host=host, port=port, log_level=log_level)
