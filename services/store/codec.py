"""Compact, exact binary forms of the TMCMC objects kept in the database.

Blobs (stage plans, batch results) are ``.npz`` archives (no pickle): every numpy array field of
the object is stored with its dtype and shape, everything else (ints, floats, prior, settings) in
a JSON header made by the object's own ``to_dict`` with the arrays left out. Decoding calls
``from_dict`` on the header and puts the arrays back, so the round trip is bit-exact, including
-inf log-likelihoods and NaN diagnostics.

Per-sample rows store vectors as little-endian float64 bytes (:func:`f64_bytes`,
:func:`f64_matrix`).
"""

from __future__ import annotations

import dataclasses
import io
import json
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.tmcmc_stage import (
    ChainBatchResult,
    PointEvaluation,
    StagePlan,
    StageState,
)

__all__ = [
    "BLOB_FORMAT",
    "BatchResult",
    "decode",
    "encode",
    "f64_bytes",
    "f64_matrix",
    "state_from_meta",
    "state_meta",
]

BLOB_FORMAT = "scm-calib-blob/1"
_HEADER = "__header__"
_KINDS: dict[str, Any] = {
    "StagePlan": StagePlan,
    "ChainBatchResult": ChainBatchResult,
    "PointEvaluation": PointEvaluation,
    "StageState": StageState,
}

BatchResult = ChainBatchResult | PointEvaluation
Encodable = StagePlan | ChainBatchResult | PointEvaluation | StageState


def _split(obj: Any) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """(to_dict of obj without its arrays, {field: array})."""
    arrays: dict[str, NDArray[Any]] = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            if value.dtype.kind not in "biuf":
                raise TypeError(f"{type(obj).__name__}.{f.name}: unsupported dtype {value.dtype}")
            arrays[f.name] = value
    meta = dataclasses.replace(obj, **dict.fromkeys(arrays)).to_dict()
    return meta, arrays


def encode(obj: Encodable) -> bytes:
    """Bytes of a StagePlan, ChainBatchResult, PointEvaluation or StageState."""
    kind = type(obj).__name__
    if kind not in _KINDS:
        raise TypeError(f"cannot encode {kind}")
    meta, arrays = _split(obj)
    header = {"format": BLOB_FORMAT, "kind": kind, "meta": meta, "arrays": sorted(arrays)}
    raw = json.dumps(header, allow_nan=False, separators=(",", ":")).encode("utf-8")
    buf = io.BytesIO()
    np.savez(buf, **{_HEADER: np.frombuffer(raw, dtype=np.uint8)}, **arrays)
    return buf.getvalue()


def decode(blob: bytes) -> Any:
    """Inverse of :func:`encode`."""
    with np.load(io.BytesIO(blob), allow_pickle=False) as archive:
        header = json.loads(archive[_HEADER].tobytes().decode("utf-8"))
        if header.get("format") != BLOB_FORMAT:
            raise ValueError(f"not a {BLOB_FORMAT} blob (format {header.get('format')!r})")
        arrays = {name: archive[name] for name in header["arrays"]}
    cls = _KINDS[header["kind"]]
    return dataclasses.replace(cls.from_dict(header["meta"]), **arrays)


def state_meta(state: StageState) -> dict[str, Any]:
    """The scalar fields of a StageState as strict JSON (its arrays live in sample rows)."""
    meta, _ = _split(state)
    arrays = ("samples", "log_likelihood", "log_prior", "responses")
    return {k: v for k, v in meta.items() if k not in arrays}


def state_from_meta(
    meta: dict[str, Any],
    samples: NDArray[np.float64],
    log_likelihood: NDArray[np.float64],
    log_prior: NDArray[np.float64],
    responses: NDArray[np.float64] | None,
) -> StageState:
    data = dict(meta, samples=None, log_likelihood=None, log_prior=None, responses=None)
    return dataclasses.replace(
        StageState.from_dict(data),
        samples=samples,
        log_likelihood=log_likelihood,
        log_prior=log_prior,
        responses=responses,
    )


def f64_bytes(row: NDArray[Any]) -> bytes:
    """A vector as little-endian float64 bytes."""
    return np.ascontiguousarray(row, dtype="<f8").tobytes()


def f64_matrix(blobs: Sequence[bytes], width: int | None = None) -> NDArray[np.float64]:
    """Rows of float64 bytes -> (n, width) float64 array (native byte order)."""
    if width is None:
        width = len(blobs[0]) // 8 if blobs else 0
    flat = np.frombuffer(b"".join(blobs), dtype="<f8")
    return flat.reshape(len(blobs), width).astype(np.float64)
