"""Compact, exact binary forms of the objects study kinds keep in the database.

The store holds stage plans and batch results as opaque blobs; a study kind makes them with
:func:`encode` and reads them with :func:`decode`, naming the class it expects. Blobs are
``.npz`` archives (no pickle): every numpy array field of the dataclass is stored with its dtype
and shape, everything else (ints, floats, prior, settings) in a JSON header made by the object's
own ``to_dict`` with the arrays left out. Decoding calls ``from_dict`` on the header and puts
the arrays back, so the round trip is bit-exact, including -inf log-likelihoods and NaN
diagnostics.

Per-sample rows store vectors as little-endian float64 bytes (:func:`f64_bytes`,
:func:`f64_matrix`).
"""

from __future__ import annotations

import dataclasses
import io
import json
from collections.abc import Sequence
from typing import Any, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

__all__ = ["BLOB_FORMAT", "decode", "encode", "f64_bytes", "f64_matrix", "split"]

BLOB_FORMAT = "scm-calib-blob/1"
_HEADER = "__header__"


class Serialisable(Protocol):
    """A dataclass with ``to_dict`` and a classmethod ``from_dict`` (arrays may be None)."""

    def to_dict(self) -> dict[str, Any]: ...


T = TypeVar("T")


def split(obj: Any) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """(``to_dict`` of the dataclass ``obj`` without its arrays, {field: array})."""
    arrays: dict[str, NDArray[Any]] = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            if value.dtype.kind not in "biuf":
                raise TypeError(f"{type(obj).__name__}.{f.name}: unsupported dtype {value.dtype}")
            arrays[f.name] = value
    meta = dataclasses.replace(obj, **dict.fromkeys(arrays)).to_dict()
    return meta, arrays


def encode(obj: Serialisable) -> bytes:
    """Bytes of a serialisable dataclass (see the module doc)."""
    if not dataclasses.is_dataclass(obj) or not hasattr(obj, "to_dict"):
        raise TypeError(f"cannot encode {type(obj).__name__}: not a dataclass with to_dict")
    meta, arrays = split(obj)
    kind = type(obj).__name__
    header = {"format": BLOB_FORMAT, "kind": kind, "meta": meta, "arrays": sorted(arrays)}
    raw = json.dumps(header, allow_nan=False, separators=(",", ":")).encode("utf-8")
    buf = io.BytesIO()
    np.savez(buf, **{_HEADER: np.frombuffer(raw, dtype=np.uint8)}, **arrays)
    return buf.getvalue()


def decode(blob: bytes, cls: type[T]) -> T:
    """Inverse of :func:`encode`; the blob must hold a ``cls``."""
    with np.load(io.BytesIO(blob), allow_pickle=False) as archive:
        header = json.loads(archive[_HEADER].tobytes().decode("utf-8"))
        if header.get("format") != BLOB_FORMAT:
            raise ValueError(f"not a {BLOB_FORMAT} blob (format {header.get('format')!r})")
        if header.get("kind") != cls.__name__:
            raise TypeError(f"blob holds a {header.get('kind')}, not a {cls.__name__}")
        arrays = {name: archive[name] for name in header["arrays"]}
    return dataclasses.replace(cls.from_dict(header["meta"]), **arrays)  # type: ignore[attr-defined]


def f64_bytes(row: NDArray[Any]) -> bytes:
    """A vector as little-endian float64 bytes."""
    return np.ascontiguousarray(row, dtype="<f8").tobytes()


def f64_matrix(blobs: Sequence[bytes], width: int | None = None) -> NDArray[np.float64]:
    """Rows of float64 bytes -> (n, width) float64 array (native byte order)."""
    if width is None:
        width = len(blobs[0]) // 8 if blobs else 0
    flat = np.frombuffer(b"".join(blobs), dtype="<f8")
    return flat.reshape(len(blobs), width).astype(np.float64)
