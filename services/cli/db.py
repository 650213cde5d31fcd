"""``scm-calib db``: create, upgrade, downgrade and inspect the service database schema.

The database is ``--url`` or the settings' ``SCM_CALIB_DATABASE_URL`` (default: the embedded
SQLite file ``scm-calib-data/scm-calib.db``). The store modules are imported only when a
command runs, so other commands do not pay for SQLAlchemy and Alembic at start-up.
"""

from __future__ import annotations

import click

_URL_HELP = "Database URL (default: SCM_CALIB_DATABASE_URL or the embedded SQLite file)."


def _resolve(url: str | None) -> str:
    if url:
        return url
    from services.config import get_settings

    return get_settings().database_url


def _fail(exc: Exception) -> click.ClickException:
    return click.ClickException(f"{type(exc).__name__}: {exc}".replace("\n", " "))


def _migrate(url: str | None, direction: str, rev: str) -> None:
    """Run Alembic's ``upgrade`` or ``downgrade`` to ``rev`` and print the revisions."""
    from services.store import migrate
    from services.store.engine import safe_url

    target = _resolve(url)
    try:
        before = migrate.current_revision(target)
        getattr(migrate, direction)(target, rev)
        after = migrate.current_revision(target)
    except Exception as exc:
        raise _fail(exc) from None
    click.echo(f"{safe_url(target)}: {before or 'base'} -> {after or 'base'}")


@click.group()
def db() -> None:
    """Database schema migrations (Alembic)."""


@db.command()
@click.option("--url", help=_URL_HELP)
@click.option("--rev", default="head", show_default=True, help="Target revision.")
def upgrade(url: str | None, rev: str) -> None:
    """Create the schema or migrate it up to REV (default: the newest)."""
    _migrate(url, "upgrade", rev)


@db.command()
@click.argument("rev")
@click.option("--url", help=_URL_HELP)
def downgrade(rev: str, url: str | None) -> None:
    """Migrate the schema down to REV ("base" drops every table, data included)."""
    _migrate(url, "downgrade", rev)


@db.command()
@click.option("--url", help=_URL_HELP)
def current(url: str | None) -> None:
    """Print the database's revision and whether it is up to date (exit 1 if not)."""
    from services.store import migrate
    from services.store.engine import safe_url

    target = _resolve(url)
    try:
        rev = migrate.current_revision(target)
        head = migrate.head_revision()
    except Exception as exc:
        raise _fail(exc) from None
    state = "up to date" if rev == head else "behind: run `scm-calib db upgrade`"
    click.echo(f"{safe_url(target)}: revision {rev or 'base'} (head {head}, {state})")
    if rev != head:
        raise SystemExit(1)
