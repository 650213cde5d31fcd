"""Lossless conversion of float arrays to strict-JSON values and back.

Floats are written as Python floats (shortest repr round-trips exactly); the non-finite values
that strict JSON lacks (-inf for failed model runs, NaN for undefined diagnostics) are written as
the strings "inf", "-inf" and "nan". Dataclasses are converted field by field from their type
annotations (:func:`dataclass_to_dict`, :func:`dataclass_from_dict`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

T = TypeVar("T")

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


# ---------------------------------------------------------------------- dataclasses


def _field_kind(hint: Any) -> Any:
    """What a field's type annotation asks for: "array", int, float, bool, str, a class with
    ``from_dict``, or None (kept as is)."""
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and len(args) == 1:
        hint = args[0]
    if hint is np.ndarray or typing.get_origin(hint) is np.ndarray:
        return "array"
    if hint in (int, float, bool, str):
        return hint
    if isinstance(hint, type) and hasattr(hint, "from_dict"):
        return hint
    return None


@functools.cache
def _kinds(cls: type) -> tuple[tuple[str, Any], ...]:
    hints = typing.get_type_hints(cls)
    return tuple((f.name, _field_kind(hints[f.name])) for f in dataclasses.fields(cls))


def dataclass_to_dict(obj: Any) -> dict[str, Any]:
    """Strict-JSON dict of a dataclass whose fields are ints, floats (non-finite as strings),
    numpy arrays (:func:`encode_array`), None, or objects with ``to_dict``; exact with
    :func:`dataclass_from_dict`. The field list is the dataclass's: nothing to keep in step."""
    out: dict[str, Any] = {}
    for name, kind in _kinds(type(obj)):
        value = getattr(obj, name)
        if value is None:
            out[name] = None
        elif kind == "array":
            out[name] = encode_array(value)
        elif kind is float:
            out[name] = encode_float(value)
        elif kind in (int, bool, str):
            out[name] = kind(value)
        elif hasattr(value, "to_dict"):
            out[name] = value.to_dict()
        else:
            out[name] = value
    return out


def dataclass_from_dict(cls: type[T], data: dict[str, Any]) -> T:
    """The dataclass ``cls`` from :func:`dataclass_to_dict`'s output (a field absent from
    ``data`` takes its default)."""
    kw: dict[str, Any] = {}
    for name, kind in _kinds(cls):
        if name not in data:
            continue
        value = data[name]
        if value is None:
            kw[name] = None
        elif kind == "array":
            kw[name] = decode_array(value)
        elif kind is float:
            kw[name] = decode_float(value)
        elif kind in (int, bool, str):
            kw[name] = kind(value)
        elif isinstance(kind, type):
            kw[name] = kind.from_dict(value)
        else:
            kw[name] = value
    return cls(**kw)


def dataclass_equal(a: Any, b: Any) -> bool:
    """Bit-identical comparison of two dataclasses of one type, field by field: arrays by
    value (NaN equal to NaN), floats with NaN equal to NaN, the rest with ``==``."""
    if type(a) is not type(b):
        return False
    for name, kind in _kinds(type(a)):
        x, y = getattr(a, name), getattr(b, name)
        if (x is None) != (y is None):
            return False
        if x is None:
            continue
        if kind == "array":
            if not np.array_equal(x, y, equal_nan=True):
                return False
        elif kind is float:
            if not (x == y or (math.isnan(x) and math.isnan(y))):
                return False
        elif kind is not None and hasattr(x, "to_dict"):
            if x.to_dict() != y.to_dict():
                return False
        elif x != y:
            return False
    return True
