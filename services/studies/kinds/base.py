"""What a study kind provides (the plug-in protocol) and the helpers kinds share.

A kind turns a request into a :class:`~services.store.StudySpec` (validation, in its module),
builds the computation of a stored study (:meth:`StudyKind.build`), computes a work batch
(:meth:`StudyRun.compute`, pure: same lease, same bytes), reduces a finished stage
(:meth:`StudyRun.reducer`) and says how many model runs each batch of a stage plans
(:meth:`StudyKind.planned_runs`, for progress). The store sees only blobs and
:class:`~services.store.ReducedStage` records; the worker sees only this protocol.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from services.store import BatchLease, BatchOutput, Reducer, Store, StudyRecord
from services.store.codec import encode

__all__ = ["ModelFunction", "StudyKind", "StudyRun", "batch_output"]

#: points (m, d) -> what the kind's batches need per point (log-likelihoods, responses ...)
ModelFunction = Callable[[NDArray[np.float64]], Any]


class StudyRun(Protocol):
    """The computation of one study, built once per process and cached."""

    @property
    def model_function(self) -> ModelFunction:
        """The function whose time is simulator time (the worker times it)."""
        ...

    def compute(self, store: Store, lease: BatchLease, model_function: Any) -> BatchOutput:
        """The result of the leased batch (the same bytes however often it runs)."""
        ...

    def reducer(self, workers: int) -> Reducer:
        """The reducer of the study's stages (next stages cut for ``workers`` workers)."""
        ...


class StudyKind(Protocol):
    """A kind of study; ``name`` is what ``studies.kind`` holds."""

    name: str

    def build(self, store: Store, study: StudyRecord) -> StudyRun:
        """The computation of ``study`` (its datasets read from the store)."""
        ...

    def planned_runs(self, plan: bytes | None, batches: Sequence[range]) -> list[int]:
        """Model runs each batch of a stage will make (``plan``: the stage's plan blob)."""
        ...


def batch_output(lease: BatchLease, result: Any) -> BatchOutput:
    """A kind's batch result (a serialisable dataclass) as the store keeps it."""
    return BatchOutput(lease.key.stage_index, lease.chain_start, lease.chain_stop, encode(result))


def one_run_per_item(batches: Sequence[range]) -> list[int]:
    """Planned runs of batches whose items (points) cost one model run each."""
    return [len(r) for r in batches]
