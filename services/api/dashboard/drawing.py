"""Study figures drawn in a process of their own, not in the API's.

Drawing a figure is seconds of matplotlib (and, for the fit, of the simulator) in one
interpreter; in the API's process it competed with every other request. :class:`FigureProcess`
keeps :data:`DRAWING_PROCESSES` spawned worker processes, each with its own store connection and
cache of simulations at the MAP, drawing one figure each at a time; the API keeps the drawn bytes
(:class:`~services.api.dashboard.study_figures.FigureCache`) and only asks the worker for what
it does not hold. The worker starts when a study page first polls (:meth:`FigureProcess.warm`: it
loads the figures' modules and the simulator's compiled code then, instead of with the first
stage's figures; not matplotlib, which the page's charts do not use: an image loads it when
first drawn) and ends with the server, even a killed one
(:func:`services.lifetime.exit_with_parent`: the kernel signals it when the thread that started
it ends, so one long-lived thread of this class starts it and hands it every figure); if it
dies, the next figure starts another. Measured with a study running beside two calibrations on
two cores (tests/web, the page fetching two figures at a time): the last stage's figures
7.9-8.2 s after the API listed it done, against 9.5-15.8 s drawn in the API's process, and the
page's progress 0.4-0.6 s behind the API against about 1 s.
"""

from __future__ import annotations

import gc
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
DRAWING_PROCESSES = 2

# the worker process's own state (set by _start_worker in that process only)
_worker: dict[str, Any] = {}


def _start_worker(database_url: str) -> None:
    from services.lifetime import exit_with_parent

    exit_with_parent()
    from services.store import Store

    from .study_figures import FigureCache

    _worker["store"] = Store.open(database_url)
    _worker["cache"] = FigureCache(max_entries=64)
    prepare_drawing()


def prepare_drawing() -> None:
    """Make this process a figure process: one numba thread, and paid now what the page's
    first charts would otherwise pay for (the figures' modules, scipy's kernel densities and
    the contour engine, the simulator's compiled kernel: the fit simulates at the MAP). Not
    matplotlib (about a second on a slow core to load it and lay out a first figure, 0.9 s at
    the lowest supported versions): the page's figures are charts, data its script draws, and
    they waited for it; an image (a download, a Morris study's indices) loads it when drawn."""
    import contourpy  # noqa: F401
    import numba
    import scipy.stats  # noqa: F401

    from scm_core.simulator import warm_up
    from services.plots import fit, posterior, stages  # noqa: F401

    from . import study_figures  # noqa: F401

    numba.set_num_threads(1)
    warm_up()
    # What is loaded now (about 200,000 objects: the modules, the compiled kernel) lives as
    # long as the process: frozen, the collector's full passes no longer walk it. One such
    # pass came every other read of a 16,000-sample stage (its rows are as many objects) and
    # took 200 ms of the read's 240 (40 ms without).
    gc.freeze()


def _draw_study_figure(study_id: int, name: str, fmt: str, options: dict[str, Any]) -> bytes:
    from .study_figures import study_figure

    store = _worker["store"]
    study = store.studies.get(study_id)
    return study_figure(store, study, name, fmt, _worker["cache"], **options)


class FigureProcess:
    """The worker processes that draw study figures for the API (see the module)."""

    def __init__(self, database_url: str) -> None:
        self.database_url = database_url
        self._jobs: queue.Queue[tuple[tuple | None, Future, int] | None] = queue.Queue()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._broken = threading.Event()  # a worker died: the serving thread starts others

    def warm(self) -> None:
        """Start the workers now, if they are not running, so that the first figures find
        them ready (returns at once; cheap when they run)."""
        if self._thread is None:
            for _ in range(DRAWING_PROCESSES):
                self._submit(None)

    def study_figure(self, study_id: int, name: str, fmt: str, options: dict[str, Any]) -> bytes:
        """The bytes of a study figure drawn in a worker (its errors raised here)."""
        return self._submit((study_id, name, fmt, options)).result()

    def _submit(self, args: tuple | None) -> Future:
        """Queue a figure (None: a task that only starts a worker)."""
        with self._lock:
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._serve, name="dashboard-figure-process", daemon=True
                )
                self._thread.start()
        done: Future = Future()
        self._jobs.put((args, done, 0))
        return done

    def _serve(self) -> None:
        """The long-lived thread that starts the workers and hands them every figure (a
        worker is spawned by the thread that submits to its pool, so this one submits all)."""
        pool: ProcessPoolExecutor | None = None
        while (job := self._jobs.get()) is not None:
            if pool is not None and self._broken.is_set():
                pool.shutdown(wait=False, cancel_futures=True)
                pool = None
            if pool is None:
                self._broken.clear()
                pool = ProcessPoolExecutor(
                    max_workers=DRAWING_PROCESSES,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=_start_worker,
                    initargs=(self.database_url,),
                )
            args = job[0]
            try:
                task = pool.submit(int) if args is None else pool.submit(_draw_study_figure, *args)
            except BrokenProcessPool:  # died since the last figure: start others, try again
                self._broken.set()
                self._jobs.put(job)
                continue
            task.add_done_callback(lambda t, job=job: self._finished(t, job))
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    def _finished(self, task: Future, job: tuple) -> None:
        args, done, attempt = job
        exc = task.exception()
        if isinstance(exc, BrokenProcessPool) and attempt == 0:
            log.warning("a figure worker died; starting others")
            self._broken.set()  # a dead worker is replaced once per figure
            self._jobs.put((args, done, 1))
        elif exc is not None:  # the figure's own error (FigureError, ...)
            done.set_exception(exc)
        else:
            done.set_result(task.result())

    def close(self) -> None:
        """Stop the thread and the workers (figures asked for before are drawn first)."""
        with self._lock:
            thread, self._thread = self._thread, None
        if thread is not None:
            self._jobs.put(None)
            thread.join(30)
