"""Plain, immutable values returned by the repositories (never live ORM objects)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import Field, dataclass, field, fields
from datetime import datetime
from typing import Any, Generic, Literal, TypeVar

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AdvanceOutcome",
    "BatchKey",
    "BatchLease",
    "BatchOutput",
    "BatchRecord",
    "CompleteOutcome",
    "DatasetRecord",
    "EventRecord",
    "Page",
    "PlannedStage",
    "ReapReport",
    "ReduceInput",
    "ReducedStage",
    "Reducer",
    "SampleArrays",
    "SamplePage",
    "StageAdvance",
    "StageRecord",
    "StudyRecord",
    "StudySpec",
    "filled_by",
    "stage_columns",
]

T = TypeVar("T")


@dataclass(frozen=True)
class Page(Generic[T]):
    """One page of a listing: ``items`` from ``offset``, ``total`` matching rows in all."""

    items: list[T]
    total: int
    limit: int
    offset: int

    @property
    def next_offset(self) -> int | None:
        nxt = self.offset + len(self.items)
        return nxt if nxt < self.total else None


@dataclass(frozen=True)
class DatasetRecord:
    id: int
    content_hash: str
    name: str
    source_kind: str
    filename: str | None
    media_type: str | None
    size_bytes: int
    meta: dict[str, Any]
    processed: dict[str, Any]
    created_at: datetime

    @property
    def means(self) -> dict[str, float]:
        """Steady means of the processed dataset, by response key."""
        return {k: float(v["mean"]) for k, v in self.processed["responses"].items()}

    @property
    def standard_errors(self) -> dict[str, float]:
        return {k: float(v["se"]) for k, v in self.processed["responses"].items()}


@dataclass(frozen=True)
class StudySpec:
    """What a new study is made of.

    case: the study's case document (free JSON to the store: the single source its kind
    derives priors and sampler settings from); ``dataset_ids`` in likelihood order. seed:
    0 <= seed < 2**63. n_samples: items of a stage (samples, design points, draws).
    kind: the plug-in that runs it (a name of ``services.studies.kinds.KINDS``). batch_size:
    items per work batch (None: the orchestrator decides). payload: the kind's own settings
    (JSON). parent_id: the stored study it starts from (an update's, a prediction's), which
    :meth:`~services.store.repositories.studies.StudyRepository.list` finds it by.
    """

    name: str
    case: Mapping[str, Any]
    dataset_ids: Sequence[int]
    seed: int
    n_samples: int
    kind: str
    batch_size: int | None = None
    payload: Mapping[str, Any] | None = None
    parent_id: int | None = None


@dataclass(frozen=True)
class StudyRecord:
    """A study; ``result``: what its kind stored when it ended (e.g. the Morris statistics of a
    sensitivity study), ``payload``: the kind's own settings."""

    id: int
    kind: str
    name: str
    status: str
    case: dict[str, Any]
    seed: int
    n_samples: int
    batch_size: int | None
    dataset_ids: tuple[int, ...]
    current_stage: int | None
    log_evidence: float | None
    log_evidence_var: float | None
    model_runs: int
    failed_runs: int
    error: str | None
    created_at: datetime
    updated_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    result: dict[str, Any] | None = None
    payload: dict[str, Any] | None = None
    #: raised by every change of the study's state (an ETag of it says "unchanged")
    version: int = 0
    #: repeated runs submitted together: the id of the group's first study (None: alone)
    run_group: int | None = None
    #: the study this one starts from (None: none)
    parent_id: int | None = None


def _column(sql: str, doc: str, *, by: tuple[str, ...] = ()) -> Any:
    """A stage field with a column of its own in the stages table: ``sql`` its SQL type
    ("real", "int", "bigint"; :mod:`.models` maps it), ``doc`` what the API says of it, ``by``
    the messages that fill it by name ("plan": :class:`PlannedStage`, "done":
    :class:`ReducedStage`'s diagnostics; the others are the store's own)."""
    return field(metadata={"column": sql, "doc": doc, "by": by})


@dataclass(frozen=True)
class StageRecord:
    """Stage ``stage_index`` of a study. Float diagnostics are None where undefined (NaN).

    The declaration of a stage's own columns (the fields with a ``column`` in their metadata,
    :func:`stage_columns`): the stages table (:class:`.models.Stage`), the API's ``StageOut``
    and the readers take their lists from it. The plan fills exponent, prev_exponent, beta,
    ess, log_evidence_increment and n_steps (:class:`PlannedStage`); the reduction fills
    acceptance, log_evidence, the run counts and again exponent, ess and n_steps
    (:class:`ReducedStage`).
    """

    id: int
    study_id: int
    stage_index: int
    status: str
    exponent: float | None = _column(
        "real", "Tempering exponent p_j (1: the posterior).", by=("plan", "done")
    )
    prev_exponent: float | None = _column(
        "real", "The previous stage's exponent p_(j-1).", by=("plan",)
    )
    beta: float | None = _column("real", "Proposal scale the stage's moves used.", by=("plan",))
    acceptance: float | None = _column(
        "real", "Acceptance rate of the stage's moves.", by=("done",)
    )
    ess: float | None = _column(
        "real", "Effective sample size of the plausibility weights.", by=("plan", "done")
    )
    log_evidence_increment: float | None = _column(
        "real", "log of the mean plausibility weight: the stage's term of log Z.", by=("plan",)
    )
    log_evidence: float | None = _column(
        "real", "log Z so far: the running sum of the terms.", by=("done",)
    )
    n_chains: int = _column("int", "Chains (or points) the stage runs.")
    n_steps: int | None = _column(
        "int", "Metropolis steps per chain (the longest chain's).", by=("plan", "done")
    )
    n_batches: int = _column("int", "Work batches the chains are split into.")
    model_runs: int | None = _column("bigint", "Model runs of the stage.")
    failed_runs: int | None = _column("bigint", "Of those, the failed ones.")
    created_at: datetime = field()
    updated_at: datetime = field()
    finished_at: datetime | None = field()
    #: a done stage's stored scalars (its kind's: a calibration's ``StageState`` without its
    #: arrays, whose counters :class:`~scm_core.inference.StageCounts` reads; the distinct
    #: samples; failed runs by reason), {} otherwise
    meta: dict[str, Any] = field(default_factory=dict)


def stage_columns() -> tuple[Field[Any], ...]:
    """The fields of :class:`StageRecord` that are columns of their own, in order."""
    return tuple(f for f in fields(StageRecord) if "column" in f.metadata)


def filled_by(message: str) -> tuple[str, ...]:
    """The columns of :class:`StageRecord` that ``message`` ("plan", "done") fills by name."""
    return tuple(f.name for f in stage_columns() if message in f.metadata["by"])


Diagnostics = Mapping[str, float | int | None]


def _check_diagnostics(given: Diagnostics, message: str) -> None:
    allowed = filled_by(message)
    unknown = sorted(set(given) - set(allowed))
    if unknown:
        raise ValueError(f"not a stage diagnostic of a {message}: {unknown}; one of {allowed}")


@dataclass(frozen=True, order=True)
class BatchKey:
    study_id: int
    stage_index: int
    batch_index: int

    def astuple(self) -> tuple[int, int, int]:
        """(study_id, stage_index, batch_index), e.g. to send to another process."""
        return (self.study_id, self.stage_index, self.batch_index)


@dataclass(frozen=True)
class BatchRecord:
    id: int
    key: BatchKey
    chain_start: int
    chain_stop: int
    status: str
    attempts: int
    worker_id: str | None
    leased_at: datetime | None
    lease_expires_at: datetime | None
    heartbeat_at: datetime | None
    dispatched_at: datetime | None
    finished_at: datetime | None
    error: str | None
    model_runs: int | None = None  # of the stored result (None: as planned)


@dataclass(frozen=True)
class BatchLease:
    """A granted lease: run chains ``chains`` of the stage, heartbeat before ``expires_at``."""

    batch_id: int
    key: BatchKey
    chain_start: int
    chain_stop: int
    worker_id: str
    attempt: int
    expires_at: datetime

    @property
    def chains(self) -> range:
        return range(self.chain_start, self.chain_stop)


@dataclass(frozen=True)
class CompleteOutcome:
    """Result of storing a batch result: "stored" (first delivery), "duplicate" (already
    stored; nothing changed) or "rejected" (batch failed or study no longer running).
    ``done``/``total``: batches of the stage done after this call."""

    status: Literal["stored", "duplicate", "rejected"]
    done: int
    total: int

    @property
    def stage_complete(self) -> bool:
        return self.done == self.total


@dataclass(frozen=True)
class ReapReport:
    """What :meth:`BatchRepository.reap` did.

    requeued: expired leases put back to pending. failed: batches over the attempt cap (their
    studies are in failed_studies). to_dispatch: pending batches to send to the broker (the
    requeued ones plus pending ones not dispatched for a while); their dispatched_at is set.
    ready_stages: (study_id, stage_index) whose batches are all done but that have not been
    advanced (e.g. the process that stored the last result died).
    """

    requeued: list[BatchKey]
    failed: list[BatchKey]
    failed_studies: list[int]
    to_dispatch: list[BatchKey]
    ready_stages: list[tuple[int, int]]


@dataclass(frozen=True)
class EventRecord:
    id: int
    study_id: int | None
    created_at: datetime
    kind: str
    payload: dict[str, Any]


@dataclass(frozen=True, eq=False)
class SampleArrays:
    """A stage's population: samples (n, d), log_likelihood and log_prior (n,), responses
    (n, k) or None; rows in sample order."""

    samples: NDArray[np.float64]
    log_likelihood: NDArray[np.float64]
    log_prior: NDArray[np.float64]
    responses: NDArray[np.float64] | None

    def __len__(self) -> int:
        return int(self.samples.shape[0])


@dataclass(frozen=True, eq=False)
class SamplePage:
    """Rows ``start`` .. ``start + len(arrays) - 1`` of a stage of ``total`` samples."""

    start: int
    total: int
    arrays: SampleArrays

    @property
    def next_start(self) -> int | None:
        nxt = self.start + len(self.arrays)
        return nxt if nxt < self.total and len(self.arrays) else None


@dataclass(frozen=True, eq=False)
class PlannedStage:
    """What the store keeps of a stage's plan: the study kind's ``blob`` (opaque here, see
    :mod:`.codec`), the number of chains (or points) its batches cover and the diagnostics
    shown with the stage, by their columns' names (those of :func:`filled_by` "plan"; a kind
    gives the ones it has)."""

    stage: int
    n_chains: int
    blob: bytes
    diagnostics: Diagnostics = field(default_factory=dict)

    def __post_init__(self) -> None:
        _check_diagnostics(self.diagnostics, "plan")


@dataclass(frozen=True, eq=False)
class ReducedStage:
    """A reduced stage: its population (stored row by row, bit-exact), the counters added to
    the study, the diagnostics shown with the stage by their columns' names (those of
    :func:`filled_by` "done"), the study's log-evidence variance so far, and ``meta``, the
    kind's own JSON about the stage (read back with the population, e.g. to rebuild its
    state)."""

    stage: int
    population: SampleArrays
    model_runs: int
    failed_runs: int
    diagnostics: Diagnostics = field(default_factory=dict)
    log_evidence_var: float | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _check_diagnostics(self.diagnostics, "done")


@dataclass(frozen=True, eq=False)
class BatchOutput:
    """A work batch's result as the store keeps it: the kind's ``blob`` and the stage and
    chain (or point) range it covers, checked against the batch it is stored for."""

    stage: int
    start: int
    stop: int
    blob: bytes
    model_runs: int | None = None  # the runs the result holds (None: as planned)


@dataclass(frozen=True)
class ReduceInput:
    """Handed to the reducer inside the advance transaction: the stage's plan blob (None for
    a stage opened without one) and its batches' result blobs in batch order."""

    study: StudyRecord
    stage: StageRecord
    plan: bytes | None
    results: list[bytes]


@dataclass(frozen=True, eq=False)
class StageAdvance:
    """The reducer's answer: the reduced stage and what comes next.

    next_plan with next_batches (consecutive ranges covering chains 0..n_chains-1) opens
    stage + 1. With next_plan None the study ends with ``final_status`` ("completed",
    "stalled" or "failed", with ``error``). ``payload``: extra fields for the "stage_done"
    event (strict JSON after non-finite floats become strings). ``result``: a JSON document
    stored on the study when it ends (e.g. the Morris statistics of a sensitivity study).
    """

    reduced: ReducedStage
    next_plan: PlannedStage | None = None
    next_batches: Sequence[range] = ()
    final_status: str | None = None
    error: str | None = None
    payload: Mapping[str, Any] | None = None
    result: Mapping[str, Any] | None = None


Reducer = Callable[[ReduceInput], StageAdvance]


@dataclass(frozen=True)
class AdvanceOutcome:
    """Result of :meth:`StageRepository.advance`.

    "advanced": this call reduced the stage (exactly one caller gets it). "already": the stage
    is not open any more (another caller advanced it). "not_ready": some batches are not done.
    "inactive": the study is not running (cancelled, failed, ...). study_status is the study's
    status after the call; next_stage the index of the stage opened, if any.
    """

    status: Literal["advanced", "already", "not_ready", "inactive"]
    study_status: str
    next_stage: int | None = None
