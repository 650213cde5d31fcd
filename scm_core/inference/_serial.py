"""Lossless conversion of float arrays and dataclasses to strict-JSON values and back.

Floats are written as Python floats (shortest repr round-trips exactly); the non-finite values
that strict JSON lacks (-inf for failed model runs, NaN for undefined diagnostics) are written as
the strings "inf", "-inf" and "nan". Arrays are ``{"shape", "dtype", "data"}`` objects.

Dataclasses are converted field by field (:func:`dataclass_to_dict`, :func:`dataclass_from_dict`)
from things this project owns, never from how a library spells its type hints (numpy 2.5 made
``NDArray`` a PEP 695 alias that ``typing.get_origin`` no longer maps to ``np.ndarray``):

* on the way out, a field's runtime value decides: arrays, floats (numpy's too), ints, bools,
  strings, None and objects with ``to_dict``; anything else is refused, so a document is always
  strict JSON;
* on the way back, the encoded form decides for arrays (an object with ``shape`` and ``data``);
  scalar and nested fields are coerced by the *text* of their own annotation (the modules use
  ``from __future__ import annotations``): ``int``, ``float``, ``bool``, ``str`` or a class of
  the dataclass's module with ``from_dict``, optionally ``| None``. Third-party names in an
  annotation are never evaluated.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import sys
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from scm_core.jsondoc import decode_float, encode_float

T = TypeVar("T")

_SCALARS: dict[str, type] = {"int": int, "float": float, "bool": bool, "str": str}


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


def is_encoded_array(value: Any) -> bool:
    """Whether ``value`` is :func:`encode_array`'s form."""
    return isinstance(value, dict) and "shape" in value and "data" in value


# ---------------------------------------------------------------------- dataclasses


def _declared_kind(annotation: Any, namespace: dict[str, Any]) -> Any:
    """int, float, bool, str, a class with ``from_dict``, or None (decided by the value and its
    encoded form) for a field annotation written as text (``"float"``, ``"int | None"``,
    ``"JointPrior"``); only builtin names and classes of the dataclass's own module are
    resolved."""
    if not isinstance(annotation, str):
        raise TypeError(
            "serialised dataclasses need text annotations (from __future__ import annotations)"
        )
    parts = [p.strip() for p in annotation.split("|")]
    parts = [p for p in parts if p != "None"]
    if len(parts) != 1:
        return None
    name = parts[0]
    if name in _SCALARS:
        return _SCALARS[name]
    if name.isidentifier():
        cls = namespace.get(name)
        if isinstance(cls, type) and hasattr(cls, "from_dict") and hasattr(cls, "to_dict"):
            return cls
    return None


@functools.cache
def _kinds(cls: type) -> tuple[tuple[str, Any], ...]:
    namespace = vars(sys.modules[cls.__module__])
    return tuple((f.name, _declared_kind(f.type, namespace)) for f in dataclasses.fields(cls))


def _encode_value(cls: type, name: str, kind: Any, value: Any) -> Any:
    if value is None:
        return None
    if isinstance(value, np.ndarray):
        return encode_array(value)
    if kind is float or isinstance(value, float | np.floating):
        return encode_float(value)
    if kind in (int, bool, str):
        return kind(value)
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, str):
        return value
    if hasattr(value, "to_dict"):
        return value.to_dict()
    raise TypeError(f"{cls.__name__}.{name}: cannot write a {type(value).__name__} as JSON")


def _decode_value(kind: Any, value: Any) -> Any:
    if value is None:
        return None
    if kind is float:
        return decode_float(value)
    if kind in (int, bool, str):
        return kind(value)
    if isinstance(kind, type):
        return kind.from_dict(value)
    if is_encoded_array(value):
        return decode_array(value)
    return value


def dataclass_to_dict(obj: Any) -> dict[str, Any]:
    """Strict-JSON dict of a dataclass whose fields are ints, floats (non-finite as strings),
    numpy arrays (:func:`encode_array`), None, or objects with ``to_dict``; exact with
    :func:`dataclass_from_dict`. The field list is the dataclass's: nothing to keep in step."""
    cls = type(obj)
    return {name: _encode_value(cls, name, kind, getattr(obj, name)) for name, kind in _kinds(cls)}


def dataclass_from_dict(cls: type[T], data: dict[str, Any]) -> T:
    """The dataclass ``cls`` from :func:`dataclass_to_dict`'s output (a field absent from
    ``data`` takes its default)."""
    kw = {name: _decode_value(kind, data[name]) for name, kind in _kinds(cls) if name in data}
    return cls(**kw)


def dataclass_equal(a: Any, b: Any) -> bool:
    """Bit-identical comparison of two dataclasses of one type, field by field: arrays by
    value (NaN equal to NaN), floats with NaN equal to NaN, the rest with ``==``."""
    if type(a) is not type(b):
        return False
    return all(_values_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))


def _values_equal(x: Any, y: Any) -> bool:
    if (x is None) or (y is None):
        return x is None and y is None
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        return (
            isinstance(x, np.ndarray)
            and isinstance(y, np.ndarray)
            and np.array_equal(x, y, equal_nan=True)
        )
    if isinstance(x, float) and isinstance(y, float):
        return x == y or (math.isnan(x) and math.isnan(y))
    if hasattr(x, "to_dict") and hasattr(y, "to_dict"):
        return x.to_dict() == y.to_dict()
    return bool(x == y)
