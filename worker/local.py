"""The embedded mode: a supervised local process pool and its loop, no broker needed.

One long-lived thread owns everything that runs work: it starts the pool's processes (so
their parent-death signal is tied to a thread that lives as long as the server), hands them
batches, replaces a process that died and gives its batch back at once, starts studies left
queued, re-dispatches pending work and advances ready stages. Request threads only queue batch
keys (:meth:`LocalRuntime.dispatch`) and wake the loop.

Leases of pool processes are held as ``local/<host>/<instance>/<pid>``, ``instance`` a random
id of this server run. At start, a server that holds this machine's runtime lock on the
database takes back at once the leases of ``local/<host>/...`` left by the server before it
(killed, crashed, restarted): its pool processes died with it. Without the lock (another
embedded server runs on the same database here) those leases are left to expire.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import logging
import socket
import tempfile
import threading
import time
import uuid
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import IO

from services.config import Settings
from services.store import Store
from services.store.engine import is_transient
from services.store.records import BatchKey

from .local_pool import Health, PoolEvent, SupervisedPool, death_reason
from .orchestrator import ContextCache, OutageLog, reap_once
from .runtime import pool_process_main

log = logging.getLogger(__name__)

#: seconds between two passes of the loop when nothing wakes it
LOOP_INTERVAL_S = 2.0
#: the loop counts as hung when its last pass is older than this
LOOP_STALE_S = 30.0


def _runtime_lock(database_url: str) -> IO[bytes] | None:
    """An exclusive lock for "the embedded runtime of this database on this machine"
    (a file in the temporary directory, named by the URL's hash); None if another process
    holds it. Released when the file is closed or the process dies."""
    digest = hashlib.sha256(database_url.encode("utf-8")).hexdigest()[:16]
    path = Path(tempfile.gettempdir()) / f"scm-calib-runtime-{digest}.lock"
    handle = open(path, "a+b")  # noqa: SIM115 (held for the runtime's life)
    try:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        return None
    return handle


class LocalRuntime:
    """Runs every study of the database on this machine (``scm-calib serve`` embedded)."""

    def __init__(self, settings: Settings, store: Store, workers: int | None = None) -> None:
        self.store = store
        self.cache = ContextCache()
        self.size = workers or settings.worker_concurrency
        self.host = socket.gethostname()
        self.instance = uuid.uuid4().hex[:12]
        self.owner = f"local/{self.host}/{self.instance}"
        self._store_args = (settings.database_url, settings.lease_seconds, settings.max_attempts)
        self._queue: deque[BatchKey] = deque()
        self._queued: set[BatchKey] = set()
        self._lock = threading.Lock()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._stop = threading.Event()
        self._pool: SupervisedPool | None = None
        self._lock_file: IO[bytes] | None = None
        self._next_reap = 0.0
        self._last_pass = time.monotonic()
        self._health = Health(False, "the local pool is starting")
        self._error: str | None = None
        self._reclaimed = False
        self._orphans: set[str] = set()  # lease holders (dead processes) not yet taken back
        self._outage = OutageLog("local runtime", LOOP_INTERVAL_S)
        self._thread = threading.Thread(target=self._run, name="scm-calib-local", daemon=True)

    # ---- any thread ----------------------------------------------------------------------

    def start(self) -> LocalRuntime:
        self._thread.start()
        return self

    def dispatch(self, keys: Sequence[BatchKey]) -> None:
        """Queue batches to run (the :class:`worker.orchestrator.Dispatcher` protocol; any
        thread). Keys already queued or running are not queued twice."""
        with self._lock:
            for k in keys:
                if k not in self._queued:
                    self._queued.add(k)
                    self._queue.append(k)
        self.kick()

    def kick(self) -> None:
        with contextlib.suppress(OSError):  # already woken (buffer full), or closed
            self._wake_w.send(b"\0")

    def health(self) -> Health:
        """Whether the loop is alive and passing, and the pool complete (readiness)."""
        if self._error is not None:
            return Health(False, self._error)
        if not self._thread.is_alive():
            return Health(False, "the local runtime's thread is not running")
        age = time.monotonic() - self._last_pass
        if age > LOOP_STALE_S:
            return Health(False, f"the local runtime's loop has not run for {age:.0f} s")
        return self._health

    @property
    def alive(self) -> bool:
        """The loop thread runs (it stops on :meth:`stop` or on an error it cannot pass)."""
        return self._thread.is_alive()

    def pids(self) -> list[int]:
        """Pids of the pool's processes (tests, diagnostics)."""
        pool = self._pool
        return pool.pids() if pool is not None else []

    def stop(self) -> None:
        self._stop.set()
        self.kick()
        self._thread.join(timeout=15)
        self._wake_r.close()
        self._wake_w.close()

    # ---- the loop thread -----------------------------------------------------------------

    def _run(self) -> None:
        try:
            self._pool = SupervisedPool(
                self.size, pool_process_main, (self._store_args, self.owner)
            )
            self._lock_file = _runtime_lock(self._store_args[0])
            self._loop()
        except Exception as exc:
            log.exception("the local runtime stopped")
            self._error = f"the local runtime stopped: {type(exc).__name__}: {exc}"
        finally:
            if self._pool is not None:
                self._pool.shutdown()
            if self._lock_file is not None:
                self._lock_file.close()

    def _reclaim_previous(self) -> None:
        """Take back the leases of the server before this one (once; a pass that cannot
        write, a storage outage at start, raises and the next pass tries again)."""
        self._reclaimed = True
        if self._lock_file is None:
            log.warning(
                "another embedded server runs on this database on this machine: leases of "
                "earlier servers are left to expire"
            )
            return
        try:
            report = self.store.batches.reclaim(f"local/{self.host}", keep=self.owner)
        except Exception:
            self._reclaimed = False
            raise
        if report.requeued or report.failed:
            log.warning(
                "took back %d batch(es) leased by the previous server here (%d failed at the "
                "attempt cap)",
                len(report.requeued),
                len(report.failed),
            )

    def _loop(self) -> None:
        pool = self._pool
        assert pool is not None
        self._next_reap = 0.0
        while not self._stop.is_set():
            try:
                self._pass(pool)
            except Exception as exc:  # a pass that failed (database gone...) is retried
                self._outage.failed(exc)
                self._stop.wait(LOOP_INTERVAL_S)
            else:
                self._outage.passed()

    def _pass(self, pool: SupervisedPool) -> None:
        if not self._reclaimed:
            self._reclaim_previous()
        self._reclaim_orphans()
        pool.ensure()
        now = time.monotonic()
        if now >= self._next_reap:
            self._next_reap = now + LOOP_INTERVAL_S
            reap_once(self.store, self.cache, self, redispatch_after=0.0)
        self._feed(pool)
        self._last_pass = time.monotonic()
        self._health = pool.health()
        events = pool.wait(LOOP_INTERVAL_S, [self._wake_r])
        self._drain_wake()
        for event in events:
            if event.outcome is not None:
                self._next_reap = 0.0  # a batch ended: its stage may be ready to advance
            self._handle(event)

    def _feed(self, pool: SupervisedPool) -> None:
        busy = pool.busy_keys
        while pool.idle:
            with self._lock:
                if not self._queue:
                    return
                key = self._queue.popleft()
                self._queued.discard(key)
            if key in busy:
                continue
            if not pool.submit(key):
                with self._lock:
                    self._queue.appendleft(key)
                    self._queued.add(key)
                return

    def _handle(self, event: PoolEvent) -> None:
        if event.died:
            log.warning(
                "local pool process %s died (%s)%s; replacing it",
                event.pid,
                death_reason(event.exitcode),
                f" while running batch {event.key.astuple()}" if event.key else "",
            )
            self._orphans.add(f"{self.owner}/{event.pid}")
            self._reclaim_orphans()
        elif event.outcome and event.outcome.startswith("error"):
            log.warning("local batch %s: %s", event.key.astuple(), event.outcome)

    def _reclaim_orphans(self) -> None:
        """Take back the leases of dead pool processes at once; one the database does not
        take now (a storage outage) is tried again every pass until it does."""
        for holder in sorted(self._orphans):
            try:
                report = self.store.batches.reclaim(holder)
            except Exception as exc:
                if not is_transient(exc):
                    log.exception("taking back the leases of %s failed", holder)
                    self._orphans.discard(holder)
                continue
            self._orphans.discard(holder)
            if report.requeued:
                self.dispatch(report.requeued)

    def _drain_wake(self) -> None:
        try:
            while self._wake_r.recv(4096):
                pass
        except (BlockingIOError, OSError):
            pass
