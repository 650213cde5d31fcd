"""Where work batches go: Celery (distributed) or a local process pool (embedded)."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from multiprocessing import get_context

from services.store.records import BatchKey

log = logging.getLogger(__name__)


class CeleryDispatcher:
    """Sends one ``scm_calib.run_batch`` task per batch to the broker."""

    def __init__(self, app) -> None:
        self.app = app

    def dispatch(self, keys: Sequence[BatchKey]) -> None:
        for k in keys:
            self.app.send_task(
                "scm_calib.run_batch", args=(k.study_id, k.stage_index, k.batch_index)
            )


class LocalDispatcher:
    """Runs batches in a local process pool; keys already queued or running are not resent."""

    def __init__(
        self,
        workers: int,
        target: Callable[[tuple, tuple[int, int, int]], str],
        store_args: tuple,
        on_done: Callable[[], None] | None = None,
        initializer: Callable[[tuple], None] | None = None,
    ) -> None:
        self._pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=get_context("spawn"),
            initializer=initializer,
            initargs=(store_args,) if initializer is not None else (),
        )
        self._target = target
        self._store_args = store_args
        self._inflight: set[BatchKey] = set()
        self._lock = threading.Lock()
        self._on_done = on_done

    def dispatch(self, keys: Sequence[BatchKey]) -> None:
        for k in keys:
            with self._lock:
                if k in self._inflight:
                    continue
                self._inflight.add(k)
            fut = self._pool.submit(
                self._target, self._store_args, (k.study_id, k.stage_index, k.batch_index)
            )
            fut.add_done_callback(lambda f, key=k: self._done(key, f))

    def _done(self, key: BatchKey, fut: Future) -> None:
        with self._lock:
            self._inflight.discard(key)
        if fut.exception() is not None:
            log.warning("local batch %s failed: %s", key, fut.exception())
        if self._on_done is not None:
            self._on_done()

    @property
    def busy(self) -> int:
        with self._lock:
            return len(self._inflight)

    def shutdown(self) -> None:
        """Stop at once: queued batches are dropped and running ones abandoned (their leases
        expire and the next server re-runs them; the store keeps every finished result)."""
        processes = list((getattr(self._pool, "_processes", None) or {}).values())
        self._pool.shutdown(wait=False, cancel_futures=True)
        for proc in processes:
            if proc.is_alive():
                proc.terminate()
        for proc in processes:
            proc.join(timeout=5)
