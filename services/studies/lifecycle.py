"""Creating and starting studies, and sending a stage's pending batches to be run."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Protocol

from services.store import BatchKey, Store, StudySpec

from .batching import work_batches

__all__ = [
    "Dispatcher",
    "create_and_start",
    "create_runs_and_start",
    "dispatch_stage",
    "start_study",
]

log = logging.getLogger(__name__)


class Dispatcher(Protocol):
    """Sends work batches somewhere they will be run (at least once)."""

    def dispatch(self, keys: Sequence[BatchKey]) -> None: ...


def create_and_start(store: Store, spec: StudySpec, dispatcher: Dispatcher | None) -> int:
    """Store a validated study and start it; returns its id. A failed dispatch is logged and
    not an error: the batches stay pending and the reaper (or the local loop) sends them."""
    return create_runs_and_start(store, [spec], dispatcher)[0]


def create_runs_and_start(
    store: Store, specs: Sequence[StudySpec], dispatcher: Dispatcher | None
) -> list[int]:
    """Store validated studies, mark two or more as one group of repeated runs
    (``run_group``), then start them; returns their ids (a failed dispatch as in
    :func:`create_and_start`)."""
    ids = [store.studies.create(spec).id for spec in specs]
    if len(ids) > 1:
        store.studies.group_runs(ids)
    for study_id in ids:
        try:
            start_study(store, study_id, dispatcher)
        except Exception:
            log.exception("dispatching study %s failed; its work will be re-dispatched", study_id)
    return ids


def start_study(store: Store, study_id: int, dispatcher: Dispatcher | None) -> None:
    """queued -> running with stage 0's batches (``n_samples`` items); dispatch them."""
    study = store.studies.get(study_id)
    stage0 = store.studies.start(study_id, work_batches(study.n_samples, study.batch_size))
    if stage0 is not None and dispatcher is not None:
        dispatch_stage(store, study_id, 0, dispatcher)


def dispatch_stage(store: Store, study_id: int, stage_index: int, dispatcher: Dispatcher) -> None:
    """Send the stage's pending batches and mark them dispatched."""
    keys = [b.key for b in store.batches.list(study_id, stage_index) if b.status == "pending"]
    if keys:
        dispatcher.dispatch(keys)
        store.batches.mark_dispatched(keys)
