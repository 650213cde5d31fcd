"""Study figures drawn in a process of their own, not in the API's.

Drawing a figure is seconds of matplotlib (and, for the fit, of the simulator) in one
interpreter; in the API's process it competed with every other request. :class:`FigureProcess`
keeps :data:`DRAWING_PROCESSES` spawned worker process with its own store connection and its own
cache of simulations at the MAP; the API keeps the drawn bytes
(:class:`~services.api.dashboard.figures.FigureCache`) and only asks the worker for what it does
not hold. The worker starts on the first figure (``scm-calib serve``: at once) and stops with the
app; if it dies, the next figure starts another. Measured with a study running beside two
calibrations on two cores (tests/web, the page fetching two figures at a time): the last
stage's figures 7.9-8.2 s after the API listed it done, against 9.5-15.8 s drawn in the API's
process, and the page's progress 0.4-0.6 s behind the API against about 1 s.
"""

from __future__ import annotations

import logging
import multiprocessing
import threading
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

__all__ = ["FigureProcess"]

log = logging.getLogger(__name__)

#: worker processes drawing at once (the page fetches two figures at a time)
DRAWING_PROCESSES = 1

# the worker process's own state (set by _start_worker in that process only)
_worker: dict[str, Any] = {}


def _start_worker(database_url: str) -> None:
    from services.store import Store

    from .figures import FigureCache

    _worker["store"] = Store.open(database_url)
    _worker["cache"] = FigureCache(max_entries=64)


def _warm_worker() -> None:
    from .figures import warm_up

    warm_up()


def _draw_study_figure(study_id: int, name: str, fmt: str, options: dict[str, Any]) -> bytes:
    from .figures import study_figure

    store = _worker["store"]
    study = store.studies.get(study_id)
    return study_figure(store, study, name, fmt, _worker["cache"], **options)


class FigureProcess:
    """One worker process that draws study figures for the API (see the module)."""

    def __init__(self, database_url: str) -> None:
        self.database_url = database_url
        self._pool: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()

    def _executor(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._pool is None:
                self._pool = ProcessPoolExecutor(
                    max_workers=DRAWING_PROCESSES,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=_start_worker,
                    initargs=(self.database_url,),
                )
            return self._pool

    def study_figure(self, study_id: int, name: str, fmt: str, options: dict[str, Any]) -> bytes:
        """The bytes of a study figure drawn in the worker (its errors raised here)."""
        pool = self._executor()
        try:
            return pool.submit(_draw_study_figure, study_id, name, fmt, options).result()
        except BrokenProcessPool:
            log.warning("the figure worker died; starting another")
            with self._lock:
                if self._pool is pool:
                    self._pool = None
            pool.shutdown(wait=False, cancel_futures=True)
            return (
                self._executor().submit(_draw_study_figure, study_id, name, fmt, options).result()
            )

    def warm(self) -> None:
        """Start the worker now and load matplotlib and the simulator in it, in the background
        (the first figure would pay for them)."""
        self._executor().submit(_warm_worker)

    def close(self) -> None:
        with self._lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
