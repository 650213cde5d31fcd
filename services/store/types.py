"""Column types shared by the models and the migrations.

* :class:`UTCDateTime`: timezone-aware UTC datetimes on every backend (SQLite keeps naive UTC
  text in one fixed format, so comparisons in SQL stay correct).
* :class:`Real`: float64 column; NaN is stored as NULL on every backend (SQLite cannot store
  NaN; PostgreSQL could, but one convention is simpler), ±inf is stored as is.
* :data:`JSONType`: JSON on both backends. Deliberately not JSONB on PostgreSQL: JSONB
  reorders object keys, and the same code must see the same documents on SQLite and
  PostgreSQL (configuration blobs are read back, never queried inside).
* :data:`BigIntId`: 64-bit autoincrement key (plain INTEGER on SQLite, where only
  ``INTEGER PRIMARY KEY`` autoincrements).
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Dialect
from sqlalchemy.types import TypeDecorator

__all__ = ["BigIntId", "JSONType", "Real", "UTCDateTime", "utcnow"]


def utcnow() -> datetime:
    return datetime.now(UTC)


class UTCDateTime(TypeDecorator[datetime]):
    """Aware UTC datetime; naive values are refused rather than guessed."""

    impl = sa.DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError(f"naive datetime {value!r}: pass an aware (UTC) datetime")
        value = value.astimezone(UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=UTC)
        return value.astimezone(UTC)


class Real(TypeDecorator[float]):
    """Double precision; NaN <-> NULL."""

    impl = sa.Double
    cache_ok = True

    def process_bind_param(self, value: Any, dialect: Dialect) -> float | None:
        if value is None:
            return None
        value = float(value)
        return None if math.isnan(value) else value

    def process_result_value(self, value: Any, dialect: Dialect) -> float | None:
        return None if value is None else float(value)


JSONType = sa.JSON()
BigIntId = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
