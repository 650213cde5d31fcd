"""The study state machine over the store: submit, run a work batch, advance a stage, reap.

The TMCMC algorithm lives in :mod:`scm_core.inference.tmcmc_stage`; this module only decides what
to run next and records it. The database owns the state: a work batch may be delivered twice (the
store counts its result once) and a stage advances exactly once (compare-and-set in the store).
Where a batch runs (a local process pool or a Celery worker) is the :class:`Dispatcher`'s business.
"""

from __future__ import annotations

import logging
import math
import os
import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Protocol

from scm_core.calibration import CaseDefinition, StudyModel
from scm_core.inference.tmcmc_stage import (
    StagePlan,
    evaluate_points,
    initial_samples,
    initial_state,
    plan_stage,
    reduce_stage,
    run_chains,
    stage_status,
)
from scm_core.signals import SWTDataset, load_log, load_summary
from services.store import Store
from services.store.codec import BatchResult
from services.store.errors import NotFoundError
from services.store.records import (
    BatchKey,
    BatchLease,
    ReduceInput,
    Reducer,
    StageAdvance,
    StudyRecord,
    StudySpec,
)

log = logging.getLogger(__name__)

DEFAULT_BATCH_SIZE = 50  # chains per work batch: ~1-2 min of simulator time at the defaults
#: workers assumed for a study's first stage (later stages count those of the previous one)
DEFAULT_WORKERS = 2
#: seconds a study may stay queued before the reaper starts it (a submission stores and starts
#: a study within milliseconds; only a submitter that died in between leaves it queued)
QUEUED_GRACE_S = 10.0


class Dispatcher(Protocol):
    """Sends work batches somewhere they will be run (at least once)."""

    def dispatch(self, keys: Sequence[BatchKey]) -> None: ...


class StudyInputError(ValueError):
    """A study cannot be made from the request; the message names the field."""


# ---------------------------------------------------------------------------- studies


def work_batches(
    n: int, batch_size: int | None, workers: int = DEFAULT_WORKERS, min_size: int | None = None
) -> list[range]:
    """Consecutive ranges covering chains (or points) 0..n-1: the work batches of a stage.

    Guided self-scheduling (Polychronopoulos and Kuck 1987): each batch takes what remains
    divided by the number of ``workers``, capped at ``batch_size`` and at least ``min_size``
    (default an eighth of ``batch_size``). A stage thus ends with short batches: workers take
    batches in order, and one that finishes early picks a short batch instead of idling at the
    stage barrier while another runs a long one. The idle time at a barrier is about half the
    duration of the last batches; each extra batch costs ~15 ms of bookkeeping (docs/store.md,
    "Where the time goes"). One worker: plain batches of ``batch_size``. Results do not depend
    on the split: chains are seeded by (study seed, stage, chain index). ``batch_size`` None:
    one batch.
    """
    if n < 1:
        raise ValueError(f"a stage needs at least one chain, got n={n}")
    if batch_size is None:
        return [range(n)]
    size = int(batch_size)
    if size < 1:
        raise ValueError(f"'batch_size' must be >= 1 or None, got {batch_size!r}")
    workers = max(1, int(workers))
    smallest = max(1, min(size, -(-size // 8) if min_size is None else int(min_size)))
    out: list[range] = []
    start = 0
    while start < n:
        k = min(size, max(smallest, math.ceil((n - start) / workers)), n - start)
        out.append(range(start, start + k))
        start += k
    return out


def service_batch_size(case: CaseDefinition, requested: int | None = None) -> int:
    """Chains per work batch of a service study: the request's, else the case's, else
    :data:`DEFAULT_BATCH_SIZE` (stages then cut it by guided self-scheduling)."""
    return int(requested or case.sampler.batch_size or DEFAULT_BATCH_SIZE)


def study_spec(
    store: Store, case: CaseDefinition, dataset_ids: Sequence[int], batch_size: int | None = None
) -> StudySpec:
    """Validated :class:`StudySpec` for ``case`` on the stored datasets ``dataset_ids``."""
    if not dataset_ids:
        raise StudyInputError("dataset_ids: at least one dataset is needed")
    if len(set(dataset_ids)) != len(dataset_ids):
        raise StudyInputError("dataset_ids: a dataset is listed twice")
    for did in dataset_ids:
        try:
            store.datasets.get(int(did))
        except NotFoundError:
            raise StudyInputError(f"dataset_ids: no dataset with id {did}") from None
    size = service_batch_size(case, batch_size)
    return StudySpec(
        name=case.name,
        case=case.to_dict(),
        priors=case.prior().to_dict(),
        dataset_ids=[int(d) for d in dataset_ids],
        seed=case.seed,
        n_samples=case.sampler.n_samples,
        sampler=case.tmcmc_settings().to_dict(),
        simulator=dict(case.simulator),
        batch_size=size,
    )


def submit_study(
    store: Store,
    case: CaseDefinition,
    dataset_ids: Sequence[int],
    dispatcher: Dispatcher | None = None,
    batch_size: int | None = None,
):
    """Create a study and start it (stage 0 batches are dispatched when a dispatcher is given)."""
    spec = study_spec(store, case, dataset_ids, batch_size)
    return store.studies.get(create_and_start(store, spec, dispatcher))


def create_and_start(store: Store, spec: StudySpec, dispatcher: Dispatcher | None) -> int:
    """Store a validated study and start it; returns its id. A failed dispatch is logged and
    not an error: the batches stay pending and the reaper (or the local loop) sends them."""
    record = store.studies.create(spec)
    try:
        start_study(store, record.id, dispatcher)
    except Exception:
        log.exception("dispatching study %s failed; its work will be re-dispatched", record.id)
    return record.id


def start_study(store: Store, study_id: int, dispatcher: Dispatcher | None) -> None:
    study = store.studies.get(study_id)
    stage0 = store.studies.start(study_id, work_batches(study.n_samples, study.batch_size))
    if stage0 is not None and dispatcher is not None:
        _dispatch_stage(store, study_id, 0, dispatcher)


def _dispatch_stage(store: Store, study_id: int, stage_index: int, dispatcher: Dispatcher) -> None:
    keys = [b.key for b in store.batches.list(study_id, stage_index) if b.status == "pending"]
    if keys:
        dispatcher.dispatch(keys)
        store.batches.mark_dispatched(keys)


# ---------------------------------------------------------------------------- models


@dataclass
class StudyContext:
    """What running a calibration's batches needs; rebuilt from the database, cached per
    process. The Morris counterpart is :class:`worker.morris_study.MorrisContext`."""

    case: CaseDefinition
    model: StudyModel
    settings: Any  # TMCMCSettings
    n_samples: int
    seed: int
    _plans: dict[int, StagePlan] = field(default_factory=dict, repr=False)

    @cached_property
    def prior(self):
        return self.case.prior()

    @cached_property
    def initial_points(self):
        """Stage-0 prior draws (all chains), drawn once per process."""
        return initial_samples(self.prior, self.n_samples, self.seed)

    @property
    def model_function(self):
        """The function whose time is simulator time: points (m, d) -> log-likelihoods."""
        return self.model.log_likelihood_batch

    def compute(self, store: Store, lease: BatchLease, model_function) -> BatchResult:
        """Run the chains (or stage-0 prior points) of one leased batch; pure computation."""
        if lease.key.stage_index == 0:
            X = self.initial_points[lease.chain_start : lease.chain_stop]
            return evaluate_points(X, model_function)
        return run_chains(self.plan(store, lease.key), lease.chains, model_function)

    def plan(self, store: Store, key: BatchKey) -> StagePlan:
        """The plan of the batch's stage, read once per process (plans never change once
        stored; the previous stage's is dropped)."""
        plan = self._plans.get(key.stage_index)
        if plan is None:
            plan = store.stages.plan(key.study_id, key.stage_index)
            self._plans = {key.stage_index: plan}
        return plan

    def reducer(self, workers: int = DEFAULT_WORKERS) -> Reducer:
        """The store's reducer: the stage's population, then the next plan or the end (its
        batches cut for ``workers`` workers, see :func:`work_batches`)."""

        def reduce(inp: ReduceInput) -> StageAdvance:
            study = inp.study
            if inp.stage.stage_index == 0:
                state = initial_state(
                    self.prior, self.initial_points, inp.results, study.seed, self.settings
                )
            else:
                state = reduce_stage(inp.plan, inp.results)
            status = stage_status(state, self.settings)
            if status is None:
                plan = plan_stage(state, self.prior, self.settings)
                batches = work_batches(plan.n_chains, study.batch_size, workers)
                return StageAdvance(state, plan, batches)
            if status == "completed":
                return StageAdvance(state, final_status="completed")
            return StageAdvance(state, final_status="stalled", error=f"TMCMC stopped: {status}")

        return reduce


class RunnableStudy(Protocol):
    """A study kind's computation: a batch's work and the reducer of its stages."""

    @property
    def model_function(self) -> Any: ...

    def compute(self, store: Store, lease: BatchLease, model_function: Any) -> BatchResult: ...

    def reducer(self, workers: int = DEFAULT_WORKERS) -> Reducer: ...


def load_datasets(store: Store, case: CaseDefinition, dataset_ids: Sequence[int]) -> list:
    """SWT datasets of a study, processed with the case's data settings (offset, cutoff)."""
    out: list[SWTDataset] = []
    for did in dataset_ids:
        rec = store.datasets.get(did)
        if rec.source_kind == "timeseries":
            raw = store.datasets.raw(did)
            out.append(
                load_log(
                    raw,
                    metadata=rec.meta or None,
                    offset=case.data.offset,
                    cutoff_hz=case.data.cutoff_hz,
                    name=rec.name,
                    keep_series=False,
                )
            )
        else:
            out.append(load_summary(store.datasets.raw(did), metadata=rec.meta or None))
    return out


def build_context(store: Store, study: StudyRecord) -> RunnableStudy:
    """The computation of ``study`` (by its kind), with its datasets loaded from the store."""
    case = CaseDefinition.from_dict(study.case)
    datasets = load_datasets(store, case, study.dataset_ids)
    if study.kind == "morris":
        from .morris_study import MorrisContext

        return MorrisContext.from_study(study, case, datasets[0])
    return StudyContext(
        case=case,
        model=StudyModel(case, datasets),
        settings=case.tmcmc_settings(),
        n_samples=study.n_samples,
        seed=study.seed,
    )


class ContextCache:
    """Per-process cache of study computations by study id (thread-safe)."""

    def __init__(self, maxsize: int = 8) -> None:
        self._items: dict[int, RunnableStudy] = {}
        self._lock = threading.Lock()
        self._maxsize = maxsize

    def get(self, store: Store, study_id: int) -> RunnableStudy:
        with self._lock:
            ctx = self._items.get(study_id)
        if ctx is not None:
            return ctx
        ctx = build_context(store, store.studies.get(study_id))
        with self._lock:
            if len(self._items) >= self._maxsize:
                self._items.pop(next(iter(self._items)))
            self._items[study_id] = ctx
        return ctx


# ---------------------------------------------------------------------------- batches


def worker_id() -> str:
    return f"{socket.gethostname()}:{os.getpid()}:{threading.get_ident()}"


class _Heartbeat:
    """Renews a lease from a background thread while a batch runs."""

    def __init__(self, store: Store, lease: BatchLease, every: float) -> None:
        self._store, self._lease, self._every = store, lease, every
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="heartbeat")

    def _run(self) -> None:
        while not self._stop.wait(self._every):
            try:
                if not self._store.batches.heartbeat(self._lease):
                    return
            except Exception:  # the next beat retries; the reaper covers a dead worker
                log.exception("heartbeat failed for %s", self._lease.key)

    def __enter__(self) -> _Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


class _TimedLikelihood:
    """The study likelihood, timing the model evaluations (simulator time) it does."""

    def __init__(self, func) -> None:
        self.func = func
        self.seconds = 0.0

    def __call__(self, X):
        t0 = time.perf_counter()
        try:
            return self.func(X)
        finally:
            self.seconds += time.perf_counter() - t0


def execute_batch(
    store: Store,
    key: BatchKey,
    cache: ContextCache,
    dispatcher: Dispatcher | None,
    worker: str | None = None,
    heartbeat_every: float | None = None,
) -> str:
    """Claim, run and store one work batch; advance its stage if it was the last one.

    Idempotent: a batch already done or leased elsewhere is skipped ("skipped"); a second
    result is not counted ("duplicate"). Returns the outcome.
    """
    lease = store.batches.claim(key, worker or worker_id())
    if lease is None:
        return "skipped"
    t0 = time.perf_counter()
    try:
        ctx = cache.get(store, key.study_id)
        timed = _TimedLikelihood(ctx.model_function)
        every = heartbeat_every or max(0.2, store.db.lease_seconds / 4.0)
        with _Heartbeat(store, lease, every):
            result = ctx.compute(store, lease, timed)
    except Exception as exc:
        log.exception("batch %s failed", key)
        store.batches.release(lease, f"{type(exc).__name__}: {exc}")
        raise
    compute_s = time.perf_counter() - t0
    done = {"worker": lease.worker_id, "compute_s": compute_s, "model_s": timed.seconds}
    outcome = store.batches.complete(key, result, event=done)
    if outcome.status == "stored" and outcome.stage_complete:
        advance(store, key.study_id, key.stage_index, cache, dispatcher)
    return outcome.status


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
        _dispatch_stage(store, study_id, stage_index + 1, dispatcher)
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
                _dispatch_stage(store, study_id, 0, dispatcher)
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
    while not stop.is_set():
        try:
            reap_once(store, cache, dispatcher, redispatch_after, queued_after)
        except Exception:
            log.exception("reaper pass failed")
        stop.wait(interval)


def wait_for_study(store: Store, study_id: int, timeout: float, poll: float = 0.5):
    """Poll until the study leaves queued/running; returns the record (tests, scripts)."""
    deadline = time.monotonic() + timeout
    while True:
        study = store.studies.get(study_id)
        if study.status not in ("queued", "running") or time.monotonic() > deadline:
            return study
        time.sleep(poll)
