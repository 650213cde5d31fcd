"""Run one stored study to its end on this machine: the command line's way of running a study.

The batches, the kinds' computations and reducers and the exactly-once advance are the
service's (:func:`~worker.orchestrator.execute_batch`), so a study run here gives the samples
a Celery or embedded-server run gives, bit for bit. In this process (``workers`` None: the
simulator's numba threads use the cores) batches run one after another; with ``workers`` they
run on the embedded server's supervised pool (:class:`~worker.local.LocalRuntime`, one numba
thread per process).

A batch that raises is given back and tried again, up to the store's attempt cap, after which
the study fails (as on the service). The caller owns the store for the run (a results folder's
database, locked by its command): leases left by an earlier run here that was stopped or
killed are given back uncounted at the start, and this run's at its end, also when Ctrl-C
stops it (KeyboardInterrupt is raised to the caller; the stages and batches already stored
stay, and running again resumes). Ctrl-C stops a simulation or a wait at once and store work at
its end (:class:`~worker.interrupt.Interrupts`), so an interrupted run leaves no transaction
open and is never lost in a garbage-collection callback.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Callable

from services.config import Settings
from services.store import Store, StudyRecord
from services.studies import start_study

from .interrupt import Interrupts
from .local import LocalRuntime
from .orchestrator import ContextCache, advance, execute_batch

__all__ = ["ACTIVE", "Watch", "run_here"]

#: a study in these states still has work to run
ACTIVE = ("queued", "running")
#: seconds between two looks at the store while a pool runs the batches
POLL_S = 0.25

#: called with the store and the study after each batch run here (in this process) or at
#: each look (on a pool); raising KeyboardInterrupt stops the run like Ctrl-C
Watch = Callable[[Store, StudyRecord], None]


def _owners() -> tuple[str, str]:
    host = socket.gethostname()
    return f"here/{host}", f"local/{host}"


def run_here(
    store: Store,
    study_id: int,
    settings: Settings,
    workers: int | None = None,
    watch: Watch | None = None,
) -> StudyRecord:
    """Run (or resume) study ``study_id`` of ``store`` until it is no longer queued or
    running; returns its record. ``settings``: the store's URL and lease policy (a pool's
    processes open the store themselves)."""
    owners = _owners()
    with Interrupts().installed() as stop:
        for owner in owners:
            store.batches.give_back(owner)
        if store.studies.get(study_id).status == "queued":
            start_study(store, study_id, None)
        try:
            if workers is None:
                return _in_process(store, study_id, f"{owners[0]}/{os.getpid()}", watch, stop)
            return _on_pool(store, study_id, settings, workers, watch, stop)
        finally:
            for owner in owners:
                store.batches.give_back(owner)


def _look(store: Store, study_id: int, watch: Watch | None, stop: Interrupts) -> StudyRecord:
    """The study now, shown to ``watch``; KeyboardInterrupt if Ctrl-C was pressed."""
    stop.check()
    study = store.studies.get(study_id)
    if watch is not None:
        watch(store, study)
    return study


def _in_process(
    store: Store, study_id: int, me: str, watch: Watch | None, stop: Interrupts
) -> StudyRecord:
    cache = ContextCache()
    while (study := _look(store, study_id, watch, stop)).status in ACTIVE:
        stage = int(study.current_stage or 0)
        batches = store.batches.list(study_id, stage)
        pending = [b.key for b in batches if b.status == "pending"]
        if pending:
            try:
                execute_batch(store, pending[0], cache, None, worker=me, interruptible=stop.open)
            except Exception:  # logged and given back: tried again up to the attempt cap
                continue
        elif batches and all(b.status == "done" for b in batches):
            advance(store, study_id, stage, cache, None)  # stopped between store and advance
        else:
            raise RuntimeError(
                f"study {study_id} is {study.status} at stage {stage} with no batch to run"
            )
    return study


def _on_pool(
    store: Store,
    study_id: int,
    settings: Settings,
    workers: int,
    watch: Watch | None,
    stop: Interrupts,
) -> StudyRecord:
    runtime = LocalRuntime(settings, store, workers).start()
    try:
        while (study := _look(store, study_id, watch, stop)).status in ACTIVE:
            if not runtime.alive:
                raise RuntimeError(runtime.health().detail)
            with stop.open():
                time.sleep(POLL_S)
        return study
    finally:
        runtime.stop()
