"""Alembic environment of the SCM calibration store.

Run through :mod:`services.store.migrate` (``scm-calib db ...``), which passes an open connection
in ``config.attributes["connection"]``. Without one, the URL comes from
``config.attributes["url"]``, the ``sqlalchemy.url`` option, or the service settings
(``SCM_CALIB_DATABASE_URL``), and an engine is made by ``services.store.engine.make_engine`` so
that SQLite gets the same pragmas and transaction handling as the application.
"""

from __future__ import annotations

from alembic import context
from sqlalchemy.engine import Connection

from services.store.models import Base

config = context.config
target_metadata = Base.metadata


def _configure(connection: Connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        render_as_batch=connection.dialect.name == "sqlite",
        compare_type=True,
        transaction_per_migration=True,
    )


def _url() -> str:
    url = config.attributes.get("url") or config.get_main_option("sqlalchemy.url")
    if url:
        return str(url)
    from services.config import get_settings

    return get_settings().database_url


def run_migrations_offline() -> None:
    from services.store.engine import normalise_url

    context.configure(
        url=normalise_url(_url()),
        target_metadata=target_metadata,
        literal_binds=True,
        dialect_opts={"paramstyle": "named"},
    )
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    connection = config.attributes.get("connection")
    if connection is not None:
        _configure(connection)
        with context.begin_transaction():
            context.run_migrations()
        return
    from services.store.engine import make_engine

    engine = make_engine(_url())
    try:
        with engine.connect() as conn:
            _configure(conn)
            with context.begin_transaction():
                context.run_migrations()
    finally:
        engine.dispose()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
