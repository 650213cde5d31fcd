"""SWT datasets: upload (multipart log or summary file, or a JSON summary), list, read, series.

Datasets are immutable and unique by content: an identical re-upload answers 200 with the
stored record instead of 201.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass, replace
from pathlib import PurePath
from typing import Annotated, Any, BinaryIO

from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from starlette.datastructures import UploadFile

from scm_core.jsondoc import finite_or_none
from scm_core.signals import LogFormatError, SWTDataset, load_dataset, load_summary
from scm_core.signals.hashing import canonical_json
from scm_core.signals.loaders import looks_like_json
from scm_core.signals.summary import MAX_SUMMARY_BYTES
from services.limits import INT64_MAX, LimitError, check_json_depth
from services.store import DatasetRecord
from services.studies.datasets import DEFAULT_OFFSET, stored_log

from ..deps import SettingsDep, StoreDep, require_read, require_write
from ..params import DatasetId
from ..schemas import DatasetOut, DatasetPage, SeriesOut
from ..upload_slots import upload_slots
from ..views import page_out
from . import errors

router = APIRouter(prefix="/datasets", tags=["datasets"], dependencies=[Depends(require_read)])

SERIES_UNITS = {
    "t": "s",
    "drawbar_pull": "N",
    "torque": "Nm",
    "sinkage": "m",
    "normal_force": "N",
    "slip": "-",
}
_HASH_CHUNK = 1 << 20

_UPLOAD_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": ["file"],
                    "properties": {
                        "file": {
                            "type": "string",
                            "format": "binary",
                            "description": "SWT log (CSV with time column) or summary "
                            "(CSV or JSON).",
                        },
                        "metadata": {
                            "type": "string",
                            "description": "JSON object: test conditions (W, slip, omega, R, "
                            "b, ...) and provenance; merged with the file's '# key: value' "
                            "lines (a condition given twice must agree).",
                        },
                        "offset": {
                            "type": "number",
                            "description": "Averaging offset of a log [s] (default 40).",
                        },
                    },
                }
            },
            "application/json": {
                "schema": {
                    "type": "object",
                    "description": "A summary dataset: {name, conditions, provenance, "
                    "responses: {F|T|z: {mean, sd, unit}}, n_trials}.",
                }
            },
        },
    }
}


def dataset_out(rec: DatasetRecord, created: bool | None = None) -> DatasetOut:
    p = rec.processed
    responses = p.get("responses") or {}
    window = p.get("window")
    return DatasetOut(
        id=rec.id,
        name=rec.name,
        content_hash=rec.content_hash,
        source_kind=rec.source_kind,
        filename=rec.filename,
        media_type=rec.media_type,
        size_bytes=rec.size_bytes,
        created_at=rec.created_at,
        conditions=dict(p.get("conditions") or {}),
        means={k: finite_or_none(v.get("mean")) for k, v in responses.items()},
        standard_errors={k: finite_or_none(v.get("se")) for k, v in responses.items()},
        offset=finite_or_none(p.get("offset")),
        window=None if window is None else [finite_or_none(w) for w in window],
        rate_hz=finite_or_none(p.get("rate_hz")),
        n_samples=p.get("n_samples"),
        n_trials=p.get("n_trials"),
        meta=rec.meta,
        created=created,
    )


def _unprocessable(message: str) -> HTTPException:
    return HTTPException(422, " ".join(message.split()))


def _too_large(size: int, limit: int, field: str = "file") -> HTTPException:
    return HTTPException(
        413,
        f"{field}: {size} bytes is over the upload limit of {limit} bytes "
        "(server setting SCM_CALIB_UPLOAD_MAX_BYTES)",
    )


def _parse_metadata(text: str | bytes | None, max_depth: int) -> dict[str, Any]:
    if text is None or (isinstance(text, str | bytes) and not text.strip()):
        return {}
    try:
        check_json_depth(text, max_depth, "metadata")
    except LimitError as exc:
        raise _unprocessable(str(exc)) from None
    try:
        doc = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _unprocessable(f"metadata: not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise _unprocessable("metadata: must be a JSON object")
    return doc


def _parse_offset(text: str | None) -> float:
    if text is None or not text.strip():
        return DEFAULT_OFFSET
    try:
        value = float(text)
    except ValueError:
        raise _unprocessable(f"offset: not a number (got {text!r})") from None
    if not (math.isfinite(value) and value >= 0):
        raise _unprocessable(f"offset: must be a number >= 0 s (got {text!r})")
    return value


def parse_upload(
    source: bytes | BinaryIO, metadata: dict[str, Any], filename: str | None, offset: float
) -> SWTDataset:
    """Validate and process an uploaded dataset (read in chunks from ``source``); 422 with the
    loader's message (line, column, unit) prefixed by ``file <name>`` (``body`` for a JSON
    summary sent as the body)."""
    label = f"file {filename}" if filename else "body"
    stream = io.BytesIO(source) if isinstance(source, bytes) else source
    stream.seek(0)
    is_json = looks_like_json(stream.read(4096))
    try:
        if is_json:  # a summary; never a stored dataset's own JSON with its hash
            ds = load_summary(stream, metadata or None)
        else:
            ds = load_dataset(stream, metadata or None, offset=offset, keep_series=False)
    except (LogFormatError, ValueError) as exc:
        message = str(exc)
        for default in ("log: ", "summary: ", "dataset: "):
            if message.startswith(default):
                message = message[len(default) :]
                break
        raise _unprocessable(f"{label}: {message}") from None
    if filename and ds.name in ("log", "summary"):
        ds = replace(ds, name=PurePath(filename).stem or ds.name)
    return ds


@dataclass
class Upload:
    """An upload as received: the file (seekable, spooled to disk when large) and the parsed
    form fields."""

    file: BinaryIO
    metadata: dict[str, Any]
    filename: str | None
    media_type: str
    offset: float


def upload_hash(file: BinaryIO, metadata: dict[str, Any], offset: float) -> str:
    """sha256 of the bytes as sent, the metadata field (canonical JSON) and the offset: equal
    for an identical re-upload, which is then answered without parsing."""
    h = hashlib.sha256(b"scm-upload/1\n")
    h.update(canonical_json({"metadata": metadata, "offset": offset}).encode("utf-8"))
    h.update(b"\n")
    file.seek(0)
    while chunk := file.read(_HASH_CHUNK):
        h.update(chunk)
    file.seek(0)
    return h.hexdigest()


@asynccontextmanager
async def _received(request: Request, limit: int, max_depth: int) -> AsyncIterator[Upload]:
    """The multipart or JSON upload of ``request`` (files closed on exit)."""
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if ctype == "multipart/form-data":
        async with request.form(max_files=2, max_fields=10) as form:
            file = form.get("file")
            if not isinstance(file, UploadFile):
                raise _unprocessable(
                    "file: required (a multipart file field 'file' with the SWT log or summary)"
                )
            size = file.size if file.size is not None else await run_in_threadpool(_size, file.file)
            if size > limit:
                raise _too_large(size, limit)
            meta_field = form.get("metadata")
            if isinstance(meta_field, UploadFile):
                meta_field = await meta_field.read()
            offset_field = form.get("offset")
            if isinstance(offset_field, UploadFile):
                raise _unprocessable("offset: must be a plain form field")
            yield Upload(
                file=file.file,
                metadata=_parse_metadata(meta_field, max_depth),
                filename=file.filename,
                media_type=file.content_type or "application/octet-stream",
                offset=_parse_offset(offset_field),
            )
        return
    if ctype == "application/json":
        raw = await request.body()
        if len(raw) > min(limit, MAX_SUMMARY_BYTES):
            raise _too_large(len(raw), min(limit, MAX_SUMMARY_BYTES), "body")
        try:
            doc = json.loads(raw)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise _unprocessable(f"body: invalid JSON ({exc})") from None
        if not isinstance(doc, dict):
            raise _unprocessable("body: a summary dataset must be a JSON object")
        yield Upload(io.BytesIO(raw), {}, None, "application/json", DEFAULT_OFFSET)
        return
    raise HTTPException(
        415,
        "Content-Type must be multipart/form-data (field 'file', optional 'metadata' JSON) "
        "or application/json (a summary dataset)",
    )


def _size(file: BinaryIO) -> int:
    file.seek(0, io.SEEK_END)
    size = file.tell()
    file.seek(0)
    return size


@router.post(
    "",
    response_model=DatasetOut,
    status_code=201,
    summary="Upload an SWT dataset",
    dependencies=[Depends(require_write)],
    openapi_extra=_UPLOAD_BODY,
    responses={
        200: {"model": DatasetOut, "description": "Identical content already stored."},
        **errors(401, 413, 415, 422, 429),
    },
)
async def upload_dataset(
    request: Request, response: Response, store: StoreDep, settings: SettingsDep
) -> DatasetOut:
    """Upload a time-series log or a summary: multipart ``file`` (+ ``metadata`` JSON object,
    ``offset`` in s), or a JSON summary document as the body. The log is validated (units,
    monotone time, finite and physically plausible values, long enough for the offset) and
    processed (filtered, steady means) in chunks. 201 when stored; 200 with the existing
    record when identical content exists (an upload identical as sent is answered before
    parsing); 413 over the size limit; 422 naming the line, column or unit of a malformed
    file; 429 with Retry-After while the most uploads at once are being processed."""
    async with (
        upload_slots(request.app, settings).hold(),
        _received(request, settings.upload_max_bytes, settings.max_json_depth) as up,
    ):
        digest = await run_in_threadpool(upload_hash, up.file, up.metadata, up.offset)
        rec = await run_in_threadpool(store.datasets.find_upload, digest)
        created = False
        if rec is None:
            ds = await run_in_threadpool(parse_upload, up.file, up.metadata, up.filename, up.offset)
            rec, created = await run_in_threadpool(
                lambda: store.datasets.add(
                    ds,
                    up.file,
                    meta=up.metadata,
                    filename=up.filename,
                    media_type=up.media_type,
                    upload_hash=digest,
                )
            )
    response.status_code = 201 if created else 200
    response.headers["Location"] = f"/datasets/{rec.id}"
    return dataset_out(rec, created)


@router.get("", response_model=DatasetPage, summary="List datasets", responses=errors(401))
def list_datasets(
    store: StoreDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
) -> DatasetPage:
    """Datasets, newest first."""
    page = store.datasets.list(limit=limit, offset=offset)
    return page_out(DatasetPage, page, dataset_out)


@router.get(
    "/{dataset_id}", response_model=DatasetOut, summary="One dataset", responses=errors(401, 404)
)
def get_dataset(dataset_id: DatasetId, store: StoreDep) -> DatasetOut:
    return dataset_out(store.datasets.get(dataset_id))


@router.get(
    "/{dataset_id}/series",
    response_model=SeriesOut,
    summary="Raw and filtered series of a log",
    responses=errors(401, 404),
)
def get_series(
    dataset_id: DatasetId,
    store: StoreDep,
    max_points: Annotated[int, Query(ge=10, le=200_000)] = 2000,
) -> SeriesOut:
    """The log's channels (SI) as uploaded and low-pass filtered, as stored processing saw
    them, decimated to at most ``max_points`` samples (every ``stride``-th), for plotting."""
    rec = store.datasets.get(dataset_id)
    try:
        ds = stored_log(store, dataset_id)
    except ValueError as exc:
        raise HTTPException(404, str(exc)) from None
    series = ds.series
    assert series is not None
    n = len(series.t)
    stride = max(1, math.ceil(n / max_points))

    def cut(a: Any) -> list[float]:
        return [float(x) for x in a[::stride]]

    return SeriesOut(
        dataset_id=rec.id,
        name=rec.name,
        units={k: v for k, v in SERIES_UNITS.items() if k == "t" or k in series.raw},
        stride=stride,
        n_total=n,
        t=cut(series.t),
        raw={k: cut(v) for k, v in series.raw.items()},
        filtered={k: cut(v) for k, v in series.filtered.items()},
        window=None if ds.window is None else [float(w) for w in ds.window],
        offset=ds.offset,
        cutoff_hz=ds.cutoff_hz,
        means={k: finite_or_none(v) for k, v in ds.means.items()},
        standard_errors={k: finite_or_none(v) for k, v in ds.standard_errors.items()},
    )
