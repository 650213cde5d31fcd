"""Study figures drawn in a process of their own, not in the API's.

Drawing a figure is seconds of matplotlib (and, for the fit, of the simulator) in one
interpreter; in the API's process it competed with every other request. :class:`FigureProcess`
keeps :data:`DRAWING_PROCESSES` spawned worker process with its own store connection and its own
cache of simulations at the MAP; the API keeps the drawn bytes
(:class:`~services.api.dashboard.figures.FigureCache`) and only asks the worker for what it does
not hold. The worker starts with the first figure and ends with the server, even a killed one
(:func:`worker.lifetime.exit_with_parent`: the kernel signals it when the thread that started
it ends, so one long-lived thread of this class starts it and hands it every figure); if it
dies, the next figure starts another. Measured with a study running beside two calibrations on
two cores (tests/web, the page fetching two figures at a time): the last stage's figures
7.9-8.2 s after the API listed it done, against 9.5-15.8 s drawn in the API's process, and the
page's progress 0.4-0.6 s behind the API against about 1 s.
"""

from __future__ import annotations

import logging
import multiprocessing
import queue
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

__all__ = ["FigureProcess"]

log = logging.getLogger(__name__)

#: worker processes drawing at once (the page fetches two figures at a time)
DRAWING_PROCESSES = 1

# the worker process's own state (set by _start_worker in that process only)
_worker: dict[str, Any] = {}


def _start_worker(database_url: str) -> None:
    from worker.lifetime import exit_with_parent

    exit_with_parent()
    from services.store import Store

    from .figures import FigureCache

    _worker["store"] = Store.open(database_url)
    _worker["cache"] = FigureCache(max_entries=64)


def _draw_study_figure(study_id: int, name: str, fmt: str, options: dict[str, Any]) -> bytes:
    from .figures import study_figure

    store = _worker["store"]
    study = store.studies.get(study_id)
    return study_figure(store, study, name, fmt, _worker["cache"], **options)


class FigureProcess:
    """The worker process that draws study figures for the API (see the module)."""

    def __init__(self, database_url: str) -> None:
        self.database_url = database_url
        self._jobs: queue.Queue[tuple[tuple, Future] | None] = queue.Queue()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    def study_figure(self, study_id: int, name: str, fmt: str, options: dict[str, Any]) -> bytes:
        """The bytes of a study figure drawn in the worker (its errors raised here)."""
        with self._lock:
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._serve, name="dashboard-figure-process", daemon=True
                )
                self._thread.start()
        done: Future = Future()
        self._jobs.put(((study_id, name, fmt, options), done))
        return done.result()

    def _serve(self) -> None:
        """The long-lived thread that starts the worker and hands it every figure."""
        pool: ProcessPoolExecutor | None = None
        while (job := self._jobs.get()) is not None:
            args, done = job
            for attempt in range(2):  # a dead worker is replaced once per figure
                if pool is None:
                    pool = ProcessPoolExecutor(
                        max_workers=DRAWING_PROCESSES,
                        mp_context=multiprocessing.get_context("spawn"),
                        initializer=_start_worker,
                        initargs=(self.database_url,),
                    )
                try:
                    done.set_result(pool.submit(_draw_study_figure, *args).result())
                    break
                except BrokenProcessPool as exc:
                    log.warning("the figure worker died; starting another")
                    pool.shutdown(wait=False, cancel_futures=True)
                    pool = None
                    if attempt:
                        done.set_exception(exc)
                except Exception as exc:  # the figure's own error (FigureError, ...)
                    done.set_exception(exc)
                    break
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    def close(self) -> None:
        """Stop the thread and the worker (figures asked for before are drawn first)."""
        with self._lock:
            thread, self._thread = self._thread, None
        if thread is not None:
            self._jobs.put(None)
            thread.join(30)
