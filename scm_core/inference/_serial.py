"""Lossless conversion of float arrays to strict-JSON values and back.

Floats are written as Python floats (shortest repr round-trips exactly); the non-finite values
that strict JSON lacks (-inf for failed model runs, NaN for undefined diagnostics) are written as
the strings "inf", "-inf" and "nan".
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

_NONFINITE = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}


def encode_float(x: float) -> float | str:
    x = float(x)
    if math.isfinite(x):
        return x
    if math.isnan(x):
        return "nan"
    return "inf" if x > 0 else "-inf"


def decode_float(x: float | int | str) -> float:
    if isinstance(x, str):
        if x not in _NONFINITE:
            raise ValueError(f"not a float encoding: {x!r}")
        return _NONFINITE[x]
    return float(x)


def encode_array(a: NDArray[Any] | None) -> dict[str, Any] | None:
    """``{"shape": [...], "data": [flat values]}``; ints stay ints."""
    if a is None:
        return None
    a = np.asarray(a)
    if a.dtype.kind in "iub":
        data: list[Any] = [int(v) for v in a.ravel()]
        return {"shape": list(a.shape), "dtype": "int64", "data": data}
    data = [encode_float(v) for v in a.astype(float).ravel()]
    return {"shape": list(a.shape), "dtype": "float64", "data": data}


def decode_array(d: dict[str, Any] | None) -> NDArray[Any] | None:
    if d is None:
        return None
    shape = tuple(int(s) for s in d["shape"])
    if d.get("dtype") == "int64":
        return np.array(d["data"], dtype=np.int64).reshape(shape)
    return np.array([decode_float(v) for v in d["data"]], dtype=float).reshape(shape)
