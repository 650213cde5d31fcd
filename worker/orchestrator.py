"""Executing studies over the store: run a work batch, advance a stage, reap lost work.

What a batch computes and how a stage is reduced is the study kind's business
(:mod:`services.studies.kinds`); this module only runs it and records it. The database owns
the state: a work batch may be delivered twice (the store counts its result once) and a stage
advances exactly once (compare-and-set in the store). Where a batch runs (a local process pool
or a Celery worker) is the :class:`~services.studies.lifecycle.Dispatcher`'s business.
"""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import threading
import time
from collections.abc import Callable
from typing import TypeVar

from scm_core.inference.wrapped import WrappedLikelihood
from services.store import Store
from services.store.engine import is_transient
from services.store.records import BatchKey, BatchLease
from services.studies.batching import DEFAULT_WORKERS
from services.studies.kinds import StudyRun, kind_of
from services.studies.lifecycle import Dispatcher, dispatch_stage, start_study

log = logging.getLogger(__name__)

T = TypeVar("T")

#: waits between attempts to store a batch's result while the database takes no writes: from
#: the first, doubling up to the longest (so a study moves within that long of the database's
#: return), for as long as the batch's lease holds
RETRY_FIRST_S = 0.1
RETRY_LONGEST_S = 2.0
#: how long a claim is retried while the database takes no writes (then the batch stays
#: pending, and the reaper dispatches it again)
CLAIM_RETRY_S = 4.0

#: seconds a study may stay queued before the reaper starts it (a submission stores and starts
#: a study within milliseconds; only a submitter that died in between leaves it queued)
QUEUED_GRACE_S = 10.0


def _line(exc: BaseException) -> str:
    """A database error in one line: the driver's message, without SQLAlchemy's SQL."""
    orig = getattr(exc, "orig", None) or exc
    return f"{type(exc).__name__}: {' '.join(str(orig).split())}"


class OutageLog:
    """One line when a loop's passes start failing on the storage (not a traceback every
    pass), one when they pass again; any other error is logged in full."""

    def __init__(self, what: str, every: float) -> None:
        self._what, self._every = what, every
        self._since: float | None = None

    def failed(self, exc: BaseException) -> None:
        if not is_transient(exc):
            log.exception("%s pass failed", self._what)
            return
        if self._since is None:
            self._since = time.monotonic()
            log.warning(
                "%s: the database is unavailable (%s); retrying every %.0f s",
                self._what,
                _line(exc),
                self._every,
            )

    def passed(self) -> None:
        if self._since is not None:
            log.warning(
                "%s: the database is back after %.1f s", self._what, time.monotonic() - self._since
            )
            self._since = None


def build_context(store: Store, study_id: int) -> StudyRun:
    """The computation of study ``study_id``, built by its kind's plug-in."""
    study = store.studies.get(study_id)
    return kind_of(study.kind).build(store, study)


class ContextCache:
    """Per-process cache of study computations by study id (thread-safe)."""

    def __init__(self, maxsize: int = 8) -> None:
        self._items: dict[int, StudyRun] = {}
        self._lock = threading.Lock()
        self._maxsize = maxsize

    def get(self, store: Store, study_id: int) -> StudyRun:
        with self._lock:
            ctx = self._items.get(study_id)
        if ctx is not None:
            return ctx
        ctx = build_context(store, study_id)
        with self._lock:
            if len(self._items) >= self._maxsize:
                self._items.pop(next(iter(self._items)))
            self._items[study_id] = ctx
        return ctx


# ---------------------------------------------------------------------------- batches


def worker_id() -> str:
    return f"{socket.gethostname()}:{os.getpid()}:{threading.get_ident()}"


class _Heartbeat:
    """Renews a lease from a background thread while a batch runs; ``renewed`` is the
    monotonic time of the last renewal (the lease holds until ``lease_seconds`` after it)."""

    def __init__(self, store: Store, lease: BatchLease, every: float) -> None:
        self._store, self._lease, self._every = store, lease, every
        self.renewed = time.monotonic()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="heartbeat")

    def _run(self) -> None:
        while not self._stop.wait(self._every):
            beat = time.monotonic()
            try:
                if not self._store.batches.heartbeat(self._lease):
                    return
                self.renewed = beat
            except Exception as exc:  # the next beat retries; the reaper covers a dead worker
                if is_transient(exc):
                    log.warning("heartbeat of %s not stored: %s", self._lease.key, _line(exc))
                else:
                    log.exception("heartbeat failed for %s", self._lease.key)

    def __enter__(self) -> _Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


class _TimedLikelihood(WrappedLikelihood):
    """The study likelihood, timing the model evaluations (simulator time) it does, each in
    ``section()`` (a run's Ctrl-C section, :meth:`worker.interrupt.Interrupts.open`)."""

    def __init__(
        self, func, section: Callable[[], contextlib.AbstractContextManager[None]] | None = None
    ) -> None:
        super().__init__(func)
        self.seconds = 0.0
        self._section = section or contextlib.nullcontext

    def around(self, evaluate):
        t0 = time.perf_counter()
        try:
            with self._section():
                return evaluate()
        finally:
            self.seconds += time.perf_counter() - t0


def is_interrupt(exc: BaseException | None) -> bool:
    """KeyboardInterrupt, possibly wrapped (numba turns one raised inside a compiled call's
    callback into a SystemError whose cause is the KeyboardInterrupt)."""
    seen = 0
    while exc is not None and seen < 10:
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc = exc.__cause__ or exc.__context__
        seen += 1
    return False


def execute_batch(
    store: Store,
    key: BatchKey,
    cache: ContextCache,
    dispatcher: Dispatcher | None,
    worker: str | None = None,
    heartbeat_every: float | None = None,
    interruptible: Callable[[], contextlib.AbstractContextManager[None]] | None = None,
) -> str:
    """Claim, run and store one work batch; advance its stage if it was the last one.

    Idempotent: a batch already done or leased elsewhere is skipped ("skipped"); a second
    result is not counted ("duplicate"). Returns the outcome. ``interruptible``: the section
    the batch's simulations run in (a command's Ctrl-C, :class:`worker.interrupt.Interrupts`).
    """
    lease = retry_while_transient(  # the first write after a storage outage may renew
        lambda: store.batches.claim(key, worker or worker_id()),
        time.monotonic() + CLAIM_RETRY_S,
        f"claiming batch {key}",
    )
    if lease is None:
        return "skipped"
    t0 = time.perf_counter()
    every = heartbeat_every or max(0.2, store.db.lease_seconds / 4.0)
    beat = _Heartbeat(store, lease, every)
    try:
        ctx = cache.get(store, key.study_id)
        timed = _TimedLikelihood(ctx.model_function, interruptible)
        with beat:
            result = ctx.compute(store, lease, timed)
    except Exception as exc:
        if is_interrupt(exc):  # stopped, not failed: the lease stays for its owner to give back
            raise KeyboardInterrupt from exc
        log.exception("batch %s failed", key)
        store.batches.release(lease, f"{type(exc).__name__}: {exc}")
        raise
    compute_s = time.perf_counter() - t0
    done = {"worker": lease.worker_id, "compute_s": compute_s, "model_s": timed.seconds}
    deadline = beat.renewed + store.db.lease_seconds
    try:
        outcome = retry_while_transient(
            lambda: store.batches.complete(key, result, event=done), deadline, f"batch {key}"
        )
    except Exception as exc:
        if is_transient(exc):  # the lease ran out: give the batch back if the store takes it
            with contextlib.suppress(Exception):
                store.batches.release(lease, f"result not stored: {type(exc).__name__}")
        raise
    if outcome.status == "stored" and outcome.stage_complete:
        advance(store, key.study_id, key.stage_index, cache, dispatcher)
    return outcome.status


def retry_while_transient(
    write: Callable[[], T],
    deadline: float,
    what: str,
    first_wait: float = RETRY_FIRST_S,
    longest_wait: float = RETRY_LONGEST_S,
) -> T:
    """``write()``, repeated while it fails with a transient database error (unreachable,
    busy, not taking writes: :func:`services.store.engine.is_transient`) and
    ``time.monotonic()`` is before ``deadline``; waits double from ``first_wait`` up to
    ``longest_wait`` seconds, so the write lands within ``longest_wait`` of the database
    taking writes again. Other errors, and the last transient one, are raised."""
    wait = first_wait
    failures = 0
    while True:
        try:
            result = write()
        except Exception as exc:
            if not is_transient(exc) or time.monotonic() + wait > deadline:
                raise
            failures += 1
            if failures == 1:
                log.warning("%s: the database did not take the write (%s); retrying", what, exc)
            time.sleep(wait)
            wait = min(2.0 * wait, longest_wait)
            continue
        if failures:
            log.warning("%s: written after %d failed attempt(s)", what, failures)
        return result


def advance(
    store: Store,
    study_id: int,
    stage_index: int,
    cache: ContextCache,
    dispatcher: Dispatcher | None,
) -> str:
    """Advance a finished stage (exactly once across all processes) and dispatch the next one."""
    ctx = cache.get(store, study_id)
    workers = store.batches.worker_count(study_id, stage_index) or DEFAULT_WORKERS
    outcome = store.stages.advance(study_id, stage_index, ctx.reducer(workers))
    if outcome.status == "advanced" and dispatcher is not None:
        dispatch_stage(store, study_id, stage_index + 1, dispatcher)
    return outcome.status


def start_stuck_studies(
    store: Store, dispatcher: Dispatcher | None, older_than: float = QUEUED_GRACE_S
) -> list[int]:
    """Start the studies left ``queued`` by a submitter that died between storing and
    starting them (fail one that cannot start, with the reason); returns their ids."""
    ids = store.studies.stuck_queued(older_than)
    for study_id in ids:
        try:
            start_study(store, study_id, None)
        except Exception as exc:
            log.exception("study %s was left queued and cannot start", study_id)
            text = " ".join(str(exc).split())
            store.studies.fail(study_id, f"could not start: {type(exc).__name__}: {text}")
            continue
        log.warning("study %s was left queued; started it", study_id)
        if dispatcher is not None:
            try:
                dispatch_stage(store, study_id, 0, dispatcher)
            except Exception:  # pending batches are re-dispatched by a later pass
                log.exception("dispatching study %s failed", study_id)
    return ids


def reap_once(
    store: Store,
    cache: ContextCache,
    dispatcher: Dispatcher,
    redispatch_after: float | None = None,
    queued_after: float = QUEUED_GRACE_S,
):
    """Start studies left queued, re-dispatch lost work (expired leases, undelivered
    batches) and advance ready stages."""
    start_stuck_studies(store, dispatcher, queued_after)
    report = store.batches.reap(redispatch_after=redispatch_after)
    if report.to_dispatch:
        dispatcher.dispatch(report.to_dispatch)
    for study_id, stage_index in report.ready_stages:
        try:
            advance(store, study_id, stage_index, cache, dispatcher)
        except Exception:
            log.exception("advancing study %s stage %s failed", study_id, stage_index)
    return report


def reap_forever(
    store: Store,
    cache: ContextCache,
    dispatcher: Dispatcher,
    interval: float,
    stop: threading.Event,
    redispatch_after: float | None = None,
    queued_after: float = QUEUED_GRACE_S,
) -> None:
    """The reaper loop (``scm-calib reaper``, or a thread of the embedded server)."""
    outage = OutageLog("reaper", interval)
    while not stop.is_set():
        try:
            reap_once(store, cache, dispatcher, redispatch_after, queued_after)
        except Exception as exc:
            outage.failed(exc)
        else:
            outage.passed()
        stop.wait(interval)


def wait_for_study(store: Store, study_id: int, timeout: float, poll: float = 0.5):
    """Poll until the study leaves queued/running; returns the record (tests, scripts)."""
    deadline = time.monotonic() + timeout
    while True:
        study = store.studies.get(study_id)
        if study.status not in ("queued", "running") or time.monotonic() > deadline:
            return study
        time.sleep(poll)
