"""Errors raised by the store."""

from __future__ import annotations

__all__ = ["InvalidStateError", "NotFoundError", "StoreError"]


class StoreError(Exception):
    """Base class of the store's errors."""


class NotFoundError(StoreError, LookupError):
    """No such dataset, study, stage or batch."""


class InvalidStateError(StoreError):
    """The operation does not apply to the object's current status."""
