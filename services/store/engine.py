"""Engines and sessions for SQLite (embedded) and PostgreSQL (distributed).

``make_engine(url)``:

* ``postgresql://`` / ``postgres://`` URLs are switched to the psycopg 3 driver
  (``postgresql+psycopg://``); connections are pre-pinged.
* SQLite files get WAL journaling, foreign keys, a busy timeout and ``synchronous=NORMAL`` on
  every connection, and the parent directory is created. SQLAlchemy emits ``BEGIN`` itself
  (the sqlite3 module's own transaction handling is switched off) so that a transaction opened
  for writing can start with ``BEGIN IMMEDIATE``: it takes SQLite's write lock up front and
  waits for it (busy timeout) instead of failing on a lock upgrade half-way. See
  :func:`write_session`. In-memory SQLite is not supported by the store (each pooled connection
  would see its own database); use a file.
* A connection that saw a write fault (:func:`is_write_fault`) is discarded, not pooled
  again: one opened while the database did not take writes would stay read-only after it does.
* JSON columns are written as strict JSON by :func:`scm_core.jsondoc.dumps`, which converts
  nothing: documents are built of plain JSON values (non-finite floats as the strings "nan",
  "inf", "-inf": :func:`scm_core.jsondoc.encode_float`), and anything else fails
  where it is written.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import URL, Engine, make_url
from sqlalchemy.orm import Session, sessionmaker

from scm_core import jsondoc

__all__ = [
    "is_sqlite",
    "is_transient",
    "is_write_fault",
    "make_engine",
    "make_sessionmaker",
    "normalise_url",
    "read_session",
    "safe_url",
    "write_session",
]

SQLITE_BUSY_TIMEOUT_S = 30.0
_BEGIN_OPTION = "scm_sqlite_begin"

#: SQLite primary result codes of a database that does not take writes: SQLITE_READONLY,
#: SQLITE_IOERR, SQLITE_FULL, SQLITE_CANTOPEN
_SQLITE_WRITE_FAULTS = {8, 10, 13, 14}
_SQLITE_FAULT_TEXT = ("readonly database", "disk i/o error", "database or disk is full")
#: PostgreSQL SQLSTATEs of the same: read_only_sql_transaction, disk_full, io_error,
#: insufficient_resources, out_of_memory
_PG_WRITE_FAULTS = {"25006", "53100", "58030", "53000", "53200"}


def normalise_url(url: str | URL) -> URL:
    """Parse ``url`` and pick the psycopg 3 driver for PostgreSQL."""
    u = make_url(url) if isinstance(url, str) else url
    if u.drivername in ("postgresql", "postgres"):
        u = u.set(drivername="postgresql+psycopg")
    return u


def safe_url(url: str | URL) -> str:
    """The URL with its password masked, for messages."""
    return normalise_url(url).render_as_string(hide_password=True)


def is_sqlite(bind: Engine | sa.Connection | Session) -> bool:
    engine = bind.get_bind() if isinstance(bind, Session) else bind
    return engine.dialect.name == "sqlite"


def is_write_fault(exc: BaseException) -> bool:
    """Whether ``exc`` (a driver error, or SQLAlchemy's wrapper of one) says the database does
    not take writes now: a read-only or vanished SQLite file, a full disk, an I/O error, a
    read-only PostgreSQL session or server."""
    orig = getattr(exc, "orig", None) or exc
    code = getattr(orig, "sqlite_errorcode", None)
    if code is not None:
        return (code & 0xFF) in _SQLITE_WRITE_FAULTS
    state = getattr(orig, "sqlstate", None) or getattr(orig, "pgcode", None)
    if state is not None:
        return state in _PG_WRITE_FAULTS
    text = str(orig).lower()
    return any(t in text for t in _SQLITE_FAULT_TEXT)


def is_transient(exc: BaseException) -> bool:
    """Whether retrying the same transaction later may succeed: the database is unreachable,
    busy or not taking writes for now (not a bad statement or a violated constraint)."""
    if isinstance(exc, sa.exc.DBAPIError) and exc.connection_invalidated:
        return True
    if isinstance(exc, sa.exc.OperationalError | sa.exc.InterfaceError):
        return True
    return isinstance(exc, sa.exc.DBAPIError) and is_write_fault(exc)


def _discard_faulty_connections(engine: Engine) -> None:
    """A connection that saw a write fault is discarded with the pool's older ones, not reused:
    a SQLite connection opened while its file was not writable stays read-only for its life,
    a PostgreSQL session opened in read-only mode stays so after the server takes writes."""

    @sa.event.listens_for(engine, "handle_error")
    def _on_error(ctx: sa.engine.ExceptionContext) -> None:
        if not ctx.is_disconnect and is_write_fault(ctx.original_exception):
            ctx.is_disconnect = True


def make_engine(url: str | URL, *, echo: bool = False, keep: bool = True, **kwargs: Any) -> Engine:
    """An engine for ``url`` set up as described in the module docstring. keep: False closes
    each SQLite connection when its transaction ends (no pool; see
    :meth:`services.store.Store.open`)."""
    u = normalise_url(url)
    if u.get_backend_name() == "sqlite":
        if not keep:
            kwargs.setdefault("poolclass", sa.pool.NullPool)
        engine = _sqlite_engine(u, echo=echo, **kwargs)
    else:
        kwargs.setdefault("pool_pre_ping", True)
        engine = sa.create_engine(u, echo=echo, json_serializer=jsondoc.dumps, **kwargs)
    _discard_faulty_connections(engine)
    return engine


def _sqlite_engine(u: URL, *, echo: bool, **kwargs: Any) -> Engine:
    database = u.database or ""
    if database in ("", ":memory:") or "mode=memory" in str(u):
        raise ValueError("the store needs a SQLite file, not an in-memory database")
    if not database.startswith("file:"):
        Path(database).expanduser().parent.mkdir(parents=True, exist_ok=True)
    connect_args = dict(kwargs.pop("connect_args", {}))
    connect_args.setdefault("timeout", SQLITE_BUSY_TIMEOUT_S)
    connect_args.setdefault("check_same_thread", False)
    engine = sa.create_engine(
        u, echo=echo, json_serializer=jsondoc.dumps, connect_args=connect_args, **kwargs
    )
    busy_ms = int(float(connect_args["timeout"]) * 1000)

    @sa.event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # SQLAlchemy emits BEGIN (below)
        cur = dbapi_connection.cursor()
        cur.execute("PRAGMA journal_mode=WAL")
        cur.execute("PRAGMA foreign_keys=ON")
        cur.execute(f"PRAGMA busy_timeout={busy_ms}")
        cur.execute("PRAGMA synchronous=NORMAL")
        cur.close()

    @sa.event.listens_for(engine, "begin")
    def _on_begin(conn: sa.Connection) -> None:
        mode = conn.get_execution_options().get(_BEGIN_OPTION, "DEFERRED")
        conn.exec_driver_sql(f"BEGIN {mode}")

    return engine


def make_sessionmaker(engine: Engine) -> sessionmaker[Session]:
    """Sessions that keep loaded attributes after commit (records are built from them)."""
    return sessionmaker(bind=engine, expire_on_commit=False, autoflush=False)


@contextmanager
def write_session(factory: sessionmaker[Session]) -> Iterator[Session]:
    """One read-write transaction: commit on success, roll back on error.

    On SQLite the transaction starts with ``BEGIN IMMEDIATE`` (writers queue on the busy
    timeout); on PostgreSQL it is an ordinary READ COMMITTED transaction and the repositories
    use row locks / conditional UPDATEs where they need them.
    """
    with factory() as session:
        if is_sqlite(session):
            session.connection(execution_options={_BEGIN_OPTION: "IMMEDIATE"})
        try:
            yield session
            session.commit()
        except BaseException:
            session.rollback()
            raise


@contextmanager
def read_session(factory: sessionmaker[Session]) -> Iterator[Session]:
    """One read-only transaction (a consistent snapshot on SQLite), rolled back at the end."""
    with factory() as session:
        try:
            yield session
        finally:
            session.rollback()
