"""Every connection reopened after a storage fault: SQLite's shared-memory index (issue 73).

A WAL database's shared-memory index (the ``-shm`` file) is mapped once per process and
database file, shared by all of that process's connections, and released only when the last
of them closes. A connection opened while the files take no writes (a read-only remount, an
I/O error, an immutable file) maps the index read-only, and every connection opened while it
lives shares that read-only map: a process whose connections overlap in time never writes
again, even once the files do. Discarding the connection that saw the fault is not enough.

So after a storage fault the engine is drained and renewed: a transaction that starts waits
until those in flight have ended (at most ``drain_timeout`` seconds), every pooled connection
is closed (``Engine.dispose``), and the next transaction opens a fresh connection that maps
the index as the files allow now. While the storage is still down, each transaction that
fails asks for another renewal, so the first one after the storage's return writes.

PostgreSQL sessions share nothing inside the client process: the renewal is off there (a
faulty connection is discarded on its own, :func:`services.store.engine.make_engine`).
"""

from __future__ import annotations

import contextlib
import gc
import logging
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from .engine import is_write_fault

__all__ = ["DRAIN_TIMEOUT_S", "FaultReset", "is_storage_fault"]

log = logging.getLogger(__name__)

#: longest wait for the transactions in flight to end before the connections are renewed;
#: past it the transaction goes on with the connections there are (and the renewal waits for
#: the next one)
DRAIN_TIMEOUT_S = 10.0


def is_storage_fault(exc: BaseException) -> bool:
    """A fault of the storage under the database (not of a statement): a file or server that
    takes no writes, an I/O error, a full disk, a lost connection."""
    if isinstance(exc, sa.exc.DBAPIError) and exc.connection_invalidated:
        return True
    return isinstance(exc, sa.exc.DBAPIError) and is_write_fault(exc)


class FaultReset:
    """Brackets every use of ``engine`` (:meth:`use`); after a storage fault seen inside one,
    renews all of the engine's connections before the next use (see the module docstring).

    enabled: False makes :meth:`use` a plain bracket (PostgreSQL). ``resets`` counts the
    renewals; :meth:`stuck_for` says how long a renewal has waited for a drain that did not
    come (a transaction that never ends: the process cannot recover by itself).
    """

    def __init__(
        self, engine: Engine, *, enabled: bool = True, drain_timeout: float = DRAIN_TIMEOUT_S
    ) -> None:
        self._engine = engine
        self.enabled = enabled
        self._drain_timeout = drain_timeout
        self._cond = threading.Condition()
        self._active = 0
        self._pending = False
        self._pending_since: float | None = None
        self._local = threading.local()
        self._opened: dict[int, Any] = {}  # the engine's DBAPI connections not yet closed
        self.resets = 0
        if enabled:
            sa.event.listen(engine, "connect", self._on_connect)
            sa.event.listen(engine, "close", self._on_close)
            sa.event.listen(engine, "close_detached", self._on_close)

    def _on_connect(self, dbapi_connection: Any, _record: Any) -> None:
        with self._cond:
            self._opened[id(dbapi_connection)] = dbapi_connection

    def _on_close(self, dbapi_connection: Any, *_: Any) -> None:
        with self._cond:
            self._opened.pop(id(dbapi_connection), None)

    def fault(self) -> None:
        """Ask for a renewal before the next use (any thread)."""
        with self._cond:
            if not self._pending:
                self._pending = True
                self._pending_since = time.monotonic()

    def stuck_for(self) -> float:
        """Seconds a renewal has been pending while uses kept going without it (0 if none):
        longer than a few drain timeouts means a connection is held for good."""
        with self._cond:
            if not self._pending or self._pending_since is None:
                return 0.0
            return time.monotonic() - self._pending_since

    @contextmanager
    def use(self) -> Iterator[None]:
        """One use of the engine (a transaction, a schema check). Nested uses in one thread
        count once (the outer one waits for the drain, the inner ones do not)."""
        if not self.enabled:
            yield
            return
        depth = getattr(self._local, "depth", 0)
        if depth == 0:
            self._enter()
        self._local.depth = depth + 1
        try:
            yield
        except Exception as exc:
            if is_storage_fault(exc):
                self.fault()
            raise
        finally:
            self._local.depth = depth
            if depth == 0:
                with self._cond:
                    self._active -= 1
                    self._cond.notify_all()

    def _close_all(self) -> None:
        """Close every connection of the engine (none is in use: called with no use active).
        ``Engine.dispose`` closes the pooled ones; a connection invalidated by the fault may
        still be referenced from its exception's traceback: close it now. A closed sqlite3
        connection whose statements are still referenced (cursors in a traceback's frames)
        stays open underneath until they are collected (``sqlite3_close_v2``), with the map:
        collect them."""
        self._engine.dispose()
        left, self._opened = list(self._opened.values()), {}
        for dbapi_connection in left:
            with contextlib.suppress(Exception):
                dbapi_connection.close()
        del left
        gc.collect()

    def _enter(self) -> None:
        with self._cond:
            if self._pending:
                deadline = time.monotonic() + self._drain_timeout
                while self._pending and self._active:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        break
                    self._cond.wait(left)
                if self._pending and not self._active:
                    self._close_all()
                    self._pending = False
                    self._pending_since = None
                    self.resets += 1
                    log.info("database connections renewed after a storage fault")
            self._active += 1
