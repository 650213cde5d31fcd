"""The embedded mode: a local process pool plus a dispatch/reap loop, no broker needed."""

from __future__ import annotations

import logging
import threading

from services.config import Settings
from services.store import Store

from .dispatch import LocalDispatcher
from .orchestrator import ContextCache, reap_once
from .runtime import init_local_process, run_local_batch

log = logging.getLogger(__name__)


class LocalRuntime:
    """Runs every study of the database on this machine (``scm-calib serve`` embedded).

    A loop re-dispatches pending work (after a restart, too) and advances ready stages; it wakes
    whenever a batch finishes. Batches run in ``workers`` processes.
    """

    def __init__(self, settings: Settings, store: Store, workers: int | None = None) -> None:
        self.store = store
        self.cache = ContextCache()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self.dispatcher = LocalDispatcher(
            workers or settings.worker_concurrency,
            run_local_batch,
            (settings.database_url, settings.lease_seconds, settings.max_attempts),
            on_done=self._wake.set,
            initializer=init_local_process,
        )
        self._thread = threading.Thread(target=self._loop, name="scm-calib-local", daemon=True)

    def start(self) -> LocalRuntime:
        self._thread.start()
        return self

    def kick(self) -> None:
        self._wake.set()

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                reap_once(self.store, self.cache, self.dispatcher, redispatch_after=0.0)
            except Exception:
                log.exception("local dispatch pass failed")
            self._wake.wait(2.0)
            self._wake.clear()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=10)
        self.dispatcher.shutdown()
