"""Fixtures of the service tests (defined in svc_support, a module with a unique name)."""

from svc_support import (
    pg_url,
    processes,
    redis_server,
    reference_prediction,
    reference_run,
    reference_samples,
    reference_update,
    svc_case,
)

__all__ = [
    "pg_url",
    "processes",
    "redis_server",
    "reference_prediction",
    "reference_run",
    "reference_samples",
    "reference_update",
    "svc_case",
]
