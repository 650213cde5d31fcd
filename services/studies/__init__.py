"""The study application service: a request (preset or case document, datasets, overrides)
becomes a validated study of some kind, checked once against the service's limits, stored and
started. Routes and CLI commands call it; it knows no HTTP and no worker (problems are
:class:`StudyRequestError`, one line naming the field, which the API answers with 422).

Layers: ``scm_core`` <- ``services.store`` <- ``services.studies`` (kinds, lifecycle) <-
``worker``, ``services.api``, ``services.cli`` (see docs/layers.md).
"""

from .batching import DEFAULT_WORKERS, work_batches
from .errors import StudyRequestError
from .intake import base_case, case_from_toml, run_specs, with_overrides
from .kinds.calibration import calibration_spec
from .kinds.checks import check_runs
from .kinds.sensitivity import sensitivity_spec
from .lifecycle import (
    Dispatcher,
    create_and_start,
    create_runs_and_start,
    dispatch_stage,
    start_study,
)

__all__ = [
    "DEFAULT_WORKERS",
    "Dispatcher",
    "StudyRequestError",
    "base_case",
    "calibration_spec",
    "case_from_toml",
    "check_runs",
    "create_and_start",
    "create_runs_and_start",
    "dispatch_stage",
    "run_specs",
    "sensitivity_spec",
    "start_study",
    "with_overrides",
    "work_batches",
]
