"""A process pool for the library's in-memory drivers (scripts and benchmarks; the command
line runs its studies through the service's batches instead, :mod:`worker.here`).

``batch_map(workers)`` is a context manager yielding a ``map(func, iterable)`` for
:func:`scm_core.calibration.run_tmcmc` / :func:`scm_core.calibration.run_sensitivity`:

* ``workers=None``: the built-in ``map``; each batch's simulations run in one
  ``simulate_packed`` call on numba's threads (all cores);
* ``workers=N``: N worker processes (spawned, so no numba thread pool is forked), each with one
  numba thread; batches are sent to them and come back in order. Ctrl-C is handled by the parent
  only (workers ignore SIGINT); leaving the block cancels batches not yet started. On Linux a
  worker is also sent SIGTERM when the parent dies, however it dies (``kill -9`` included), so
  no worker keeps simulating an orphaned batch.

Every simulated row is independent of the others and of the batch it is in, so results are
bit-identical for any ``workers``.
"""

from __future__ import annotations

import multiprocessing
import signal
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any

from services.lifetime import exit_with_parent

MapFn = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]


def _init_worker() -> None:
    exit_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    import numba

    numba.set_num_threads(1)


@contextmanager
def batch_map(workers: int | None) -> Iterator[MapFn]:
    """A ``map`` running batches in-process (None) or on ``workers`` processes."""
    if workers is None:
        yield map
        return
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    ctx = multiprocessing.get_context("spawn")
    executor = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=ctx,
        initializer=_init_worker,
    )
    try:
        yield executor.map
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
