"""Schema migrations (Alembic), driven programmatically: no ``alembic.ini`` is needed.

The revisions live in ``migrations/`` at the top of the repository. :func:`migrations_dir`
finds it: ``$SCM_CALIB_MIGRATIONS_DIR`` if set, else the directory two levels above this
package (``<repo>/migrations``), which is where it is in a source checkout and in an editable
install. A wheel built from the current ``pyproject.toml`` does not contain it; there, set
``SCM_CALIB_MIGRATIONS_DIR``.

:func:`check_revision` is what the API, the workers and the CLI call before touching the
database: it raises :class:`SchemaVersionError` unless the database is at the head revision.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy.engine import URL, Connection, Engine

from .engine import make_engine, safe_url

__all__ = [
    "MIGRATIONS_ENV",
    "SchemaVersionError",
    "alembic_config",
    "check_revision",
    "current_revision",
    "downgrade",
    "head_revision",
    "migrations_dir",
    "revision",
    "upgrade",
]

MIGRATIONS_ENV = "SCM_CALIB_MIGRATIONS_DIR"
UPGRADE_HINT = "scm-calib db upgrade"


class SchemaVersionError(RuntimeError):
    """The database schema is not the revision this code was written for."""

    def __init__(self, current: str | None, head: str, url: str = "") -> None:
        self.current = current
        self.head = head
        where = f" ({url})" if url else ""
        super().__init__(
            f"database{where} at revision {current or 'base (empty)'}, code needs {head}: "
            f"run `{UPGRADE_HINT}`"
        )


def migrations_dir() -> Path:
    """The Alembic script directory (see module docstring)."""
    env = os.environ.get(MIGRATIONS_ENV)
    path = Path(env) if env else Path(__file__).resolve().parents[2] / "migrations"
    if not (path / "env.py").is_file():
        raise FileNotFoundError(
            f"no Alembic migrations at {path}; run from a source checkout or editable install, "
            f"or set {MIGRATIONS_ENV} to the repository's migrations/ directory"
        )
    return path


def alembic_config(url: str | URL | None = None, connection: Connection | None = None) -> Config:
    """An Alembic Config for ``migrations/`` (``url`` or an open ``connection``)."""
    cfg = Config()
    cfg.set_main_option("script_location", str(migrations_dir()))
    if url is not None:
        cfg.attributes["url"] = str(url) if isinstance(url, str) else url.render_as_string(False)
    if connection is not None:
        cfg.attributes["connection"] = connection
    return cfg


def _url(url: str | URL | None) -> str | URL:
    if url is not None:
        return url
    from services.config import get_settings

    return get_settings().database_url


def _run(url: str | URL | None, action: str, rev: str) -> None:
    engine = make_engine(_url(url))
    try:
        with engine.connect() as conn:
            cfg = alembic_config(connection=conn)
            getattr(command, action)(cfg, rev)
            if conn.in_transaction():
                conn.commit()
    finally:
        engine.dispose()


def upgrade(url: str | URL | None = None, rev: str = "head") -> None:
    """Migrate the database at ``url`` (default: the settings' database) up to ``rev``."""
    _run(url, "upgrade", rev)


def downgrade(url: str | URL | None, rev: str) -> None:
    """Migrate the database at ``url`` down to ``rev`` (``"base"``: drop all tables)."""
    _run(url, "downgrade", rev)


@functools.lru_cache(maxsize=1)
def head_revision() -> str:
    """The newest revision in ``migrations/versions`` (read once per process: the code that
    runs is the code that started, whatever appears on disk later)."""
    head = ScriptDirectory.from_config(alembic_config()).get_current_head()
    if head is None:
        raise RuntimeError(f"no revisions in {migrations_dir()}")
    return head


def _current(conn: Connection) -> str | None:
    return MigrationContext.configure(conn).get_current_revision()


def current_revision(bind: str | URL | Engine | None = None) -> str | None:
    """The database's revision (None: no schema, i.e. base)."""
    if isinstance(bind, Engine):
        with bind.connect() as conn:
            return _current(conn)
    engine = make_engine(_url(bind))
    try:
        with engine.connect() as conn:
            return _current(conn)
    finally:
        engine.dispose()


def check_revision(engine: Engine) -> str:
    """Return the head revision if the database is at it, else raise SchemaVersionError."""
    head = head_revision()
    current = current_revision(engine)
    if current != head:
        raise SchemaVersionError(current, head, safe_url(engine.url))
    return head


def revision(
    message: str, url: str | URL | None = None, autogenerate: bool = True, rev_id: str | None = None
) -> None:
    """Draft a new revision (developers; compare against the database at ``url``)."""
    engine = make_engine(_url(url))
    try:
        with engine.connect() as conn:
            cfg = alembic_config(connection=conn)
            command.revision(cfg, message=message, autogenerate=autogenerate, rev_id=rev_id)
    finally:
        engine.dispose()
