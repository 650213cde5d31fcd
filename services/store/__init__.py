"""Persistence of the calibration service: SQLAlchemy 2 models, repositories, migrations.

Entry point: :class:`Store` (``Store.open(url)`` or ``Store.from_settings()``), whose
repositories (``datasets``, ``studies``, ``stages``, ``batches``, ``samples``, ``events``) each
run one transaction per method. Schema: :mod:`.models`; migrations: :mod:`.migrate`.
"""

from .errors import InvalidStateError, NotFoundError, StoreError
from .migrate import SchemaVersionError, check_revision, current_revision, downgrade, upgrade
from .records import (
    AdvanceOutcome,
    BatchKey,
    BatchLease,
    BatchOutput,
    BatchRecord,
    CompleteOutcome,
    DatasetRecord,
    EventRecord,
    Page,
    PlannedStage,
    ReapReport,
    ReducedStage,
    ReduceInput,
    Reducer,
    SampleArrays,
    SamplePage,
    StageAdvance,
    StageRecord,
    StudyRecord,
    StudySpec,
    filled_by,
    stage_columns,
)
from .store import Store

__all__ = [
    "AdvanceOutcome",
    "BatchKey",
    "BatchLease",
    "BatchOutput",
    "BatchRecord",
    "CompleteOutcome",
    "DatasetRecord",
    "EventRecord",
    "InvalidStateError",
    "NotFoundError",
    "Page",
    "PlannedStage",
    "ReapReport",
    "ReduceInput",
    "ReducedStage",
    "Reducer",
    "SampleArrays",
    "SamplePage",
    "SchemaVersionError",
    "StageAdvance",
    "StageRecord",
    "Store",
    "StoreError",
    "StudyRecord",
    "StudySpec",
    "check_revision",
    "current_revision",
    "downgrade",
    "filled_by",
    "stage_columns",
    "upgrade",
]
