"""The study application service: a request (preset or case document, datasets, overrides)
becomes a validated study, checked once against the service's limits and stored and started.
Routes call it; it knows no HTTP (problems are :class:`StudyRequestError`, one line naming the
field, which the API answers with 422)."""

from worker.orchestrator import create_and_start

from .intake import (
    StudyRequestError,
    base_case,
    calibration_spec,
    check_runs,
    sensitivity_request,
    with_overrides,
)

__all__ = [
    "StudyRequestError",
    "base_case",
    "calibration_spec",
    "check_runs",
    "create_and_start",
    "sensitivity_request",
    "with_overrides",
]
