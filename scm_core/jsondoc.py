"""Strict JSON text of a document (the one writer of every JSON file and JSON column).

A document is made of plain JSON values only: dicts with string keys, lists, str, int, float
(finite), bool and None. Non-finite floats travel as the strings "nan", "inf" and "-inf" and
arrays as :func:`scm_core.inference._serial.encode_array` objects, converted where the document
is built. Nothing is converted here: ``json.dumps(..., allow_nan=False)`` without an encoder, so
a NaN or a numpy value that slips into a document fails where it is written, naming its type,
instead of being written as something no reader can take back.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["decode_float", "dumps", "encode_float", "finite_or_none"]

_NONFINITE = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}


def encode_float(x: float) -> float | str:
    """A float as a strict-JSON value: itself, or "nan", "inf", "-inf"."""
    x = float(x)
    if math.isfinite(x):
        return x
    if math.isnan(x):
        return "nan"
    return "inf" if x > 0 else "-inf"


def finite_or_none(x: Any) -> float | None:
    """A float for a JSON value that has no room for NaN or infinity: the finite float, or None
    (also for what is not a number)."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def decode_float(x: float | int | str) -> float:
    """The float :func:`encode_float` wrote."""
    if isinstance(x, str):
        if x not in _NONFINITE:
            raise ValueError(f"not a float encoding: {x!r}")
        return _NONFINITE[x]
    return float(x)


def dumps(doc: Any, *, indent: int | None = None) -> str:
    """``json.dumps(doc, allow_nan=False)``: compact, or indented by ``indent``."""
    separators = (",", ":") if indent is None else (",", ": ")
    return json.dumps(doc, allow_nan=False, indent=indent, separators=separators)
