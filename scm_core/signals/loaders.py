"""Loading and writing SWT datasets from files or uploaded bytes (the only module doing I/O)."""

import io
import json
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from .conditions import TestConditions
from .csvtext import TableReader, text_lines
from .dataset import DICT_FORMAT, SWTDataset, SWTSeries
from .errors import LogFormatError
from .hashing import finish_log_hash, log_digest, summary_hash
from .logformat import RESPONSE_COLUMNS, format_log, parse_header_field, parse_log_stream
from .metadata import Metadata, merge_metadata
from .processing import DEFAULT_ORDER, lowpass, steady_response
from .summary import MAX_SUMMARY_BYTES, Summary, parse_summary_csv, parse_summary_json
from .validation import MAX_JITTER, MIN_WINDOW_SAMPLES, check_time_axis, window_mask

#: a path, bytes in memory, or a seekable binary file (read from its start)
Source = str | os.PathLike[str] | bytes | BinaryIO


@contextmanager
def _open(source: Source) -> Iterator[tuple[BinaryIO, Path | None]]:
    """A binary stream at the start of ``source`` and its path (None for bytes and files)."""
    if isinstance(source, bytes | bytearray):
        yield io.BytesIO(source), None
    elif hasattr(source, "read"):
        source.seek(0)
        yield source, None
    else:
        path = Path(source)
        with path.open("rb") as stream:
            yield stream, path


def _read_small(stream: BinaryIO, label: str) -> bytes:
    """The whole of a summary or JSON dataset, refused past :data:`MAX_SUMMARY_BYTES`."""
    data = stream.read(MAX_SUMMARY_BYTES + 1)
    if len(data) > MAX_SUMMARY_BYTES:
        raise LogFormatError(
            f"{label}: over {MAX_SUMMARY_BYTES} bytes, too large for a summary or JSON dataset "
            "(a time-series log is CSV with a time column)"
        )
    return data


def _label(path: Path | None, name: str | None, default: str) -> str:
    return path.name if path is not None else (name or default)


def read_sidecar(path: Path) -> dict[str, Any]:
    """The metadata of a log's JSON sidecar (same stem, ``.json``; {} if there is none)."""
    sidecar = Path(path).with_suffix(".json")
    if sidecar == Path(path):
        return {}
    if not sidecar.is_file():
        return {}
    try:
        doc = json.loads(sidecar.read_text(encoding="utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LogFormatError(f"sidecar {sidecar.name}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise LogFormatError(f"sidecar {sidecar.name}: top level must be an object")
    return doc


def _metadata_dict(meta: Metadata) -> dict[str, Any]:
    return {"conditions": meta.conditions.to_dict(), "provenance": meta.provenance}


def load_log(
    source: Source,
    metadata: Mapping[str, Any] | None = None,
    offset: float = 40.0,
    cutoff_hz: float | None = None,
    *,
    name: str | None = None,
    order: int = DEFAULT_ORDER,
    sidecar: bool = True,
    keep_series: bool = True,
    min_window_samples: int = MIN_WINDOW_SAMPLES,
    max_jitter: float = MAX_JITTER,
) -> SWTDataset:
    """Read, validate and process a time-series SWT log (CSV path or uploaded bytes).

    Metadata merge order: ``# key: value`` lines in the file, the JSON sidecar (same stem,
    ``.json``; paths only, unless ``sidecar=False``), then ``metadata``; a condition given twice
    must agree. Steady means after ``offset`` s from the first sample (paper: 40 s), low-pass
    ``cutoff_hz`` (None: min(1 Hz, 0.2 x rate)). Raises :class:`LogFormatError` naming the
    file, line, column or unit; ``ValueError`` for bad parameters (cutoff above Nyquist).
    """
    with _open(source) as (stream, path):
        label = _label(path, name, "log")
        digest = log_digest()
        try:
            table = parse_log_stream(stream, digest)
            side = read_sidecar(path) if (path is not None and sidecar) else {}
            meta = merge_metadata(
                [("file header", table.metadata), ("sidecar", side), ("metadata", metadata or {})]
            )
            t = table.columns["time"]
            rate = check_time_axis(t, table.lines, max_jitter=max_jitter)
            window_mask(t, offset, min_window_samples)
        except LogFormatError as exc:
            raise LogFormatError(f"{label}: {exc}") from None
    cols = table.columns
    F, T, z, Fy = (cols.get(column) for column in RESPONSE_COLUMNS)
    steady = steady_response(t, F, T, z, offset, cutoff_hz, order, Fy)
    series = None
    if keep_series:
        raw = {k: v for k, v in cols.items() if k != "time"}
        filtered = {k: lowpass(v, rate, steady.cutoff_hz, order) for k, v in raw.items()}
        series = SWTSeries(t, raw, filtered)
    return SWTDataset(
        name=name or str(meta.provenance.get("name") or (path.stem if path else "log")),
        conditions=meta.conditions,
        responses=steady.stats(),
        source_kind="timeseries",
        content_hash=finish_log_hash(digest, _metadata_dict(meta)),
        provenance=meta.provenance,
        window=steady.window,
        n_samples=steady.n_samples,
        rate_hz=steady.rate_hz,
        offset=float(offset),
        cutoff_hz=steady.cutoff_hz,
        series=series,
    )


def looks_like_json(head: bytes) -> bool:
    """Whether the first bytes of a file start a JSON object (BOM and blanks skipped)."""
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{")


def _is_json(data: bytes, path: Path | None) -> bool:
    if path is not None and path.suffix.lower() in (".json", ".csv"):
        return path.suffix.lower() == ".json"
    return looks_like_json(data)


def _summary_dataset(summary: Summary, name: str) -> SWTDataset:
    meta = summary.metadata
    content = {
        **_metadata_dict(meta),
        "responses": {k: {"mean": s.mean, "sd": s.sd} for k, s in summary.stats.items()},
        "n_trials": summary.n_trials,
    }
    return SWTDataset(
        name=name,
        conditions=meta.conditions,
        responses=dict(summary.stats),
        source_kind="summary",
        content_hash=summary_hash(content),
        provenance=meta.provenance,
        n_trials=summary.n_trials,
    )


def load_summary(
    source: Source | Mapping[str, Any],
    metadata: Mapping[str, Any] | None = None,
    *,
    name: str | None = None,
) -> SWTDataset:
    """Read a summary dataset (JSON or CSV path, uploaded bytes, or a decoded JSON dict).

    The content hash covers the parsed SI content (conditions, provenance, means, sds, trial
    count), so the JSON and CSV forms of the same numbers hash alike.
    """
    path = None
    try:
        if isinstance(source, Mapping):
            summary = parse_summary_json(source, metadata)
        else:
            with _open(source) as (stream, path):
                data = _read_small(stream, _label(path, name, "summary"))
            parse = parse_summary_json if _is_json(data, path) else parse_summary_csv
            summary = parse(data, metadata)
    except LogFormatError as exc:
        message = str(exc)
        label = _label(path, name, "summary")
        raise LogFormatError(
            message if message.startswith(label) else f"{label}: {message}"
        ) from None
    default = summary.name or (path.stem if path else "summary")
    return _summary_dataset(summary, name or default)


def load_dataset(
    source: Source, metadata: Mapping[str, Any] | None = None, **log_options: Any
) -> SWTDataset:
    """Load any dataset file or upload, dispatching on extension and content.

    JSON: a stored dataset (``to_dict`` output) or a summary. CSV: a time-series log when the
    header has a time column, else a summary. ``log_options`` go to :func:`load_log`.
    """
    name = log_options.pop("name", None)
    with _open(source) as (stream, path):
        label = _label(path, name, "dataset")
        if path is not None and path.suffix.lower() == ".toml":
            raise LogFormatError(
                f"{label}: a case file (TOML), not a lab file: `scm-calib calibrate {path}` "
                "runs it; check the logs and summaries it names"
            )
        head = stream.read(4096)
        if _is_json(head, path):
            stream.seek(0)
            data = _read_small(stream, label)
            try:
                doc = json.loads(data.decode("utf-8-sig"))
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise LogFormatError(f"{label}: not valid JSON ({exc})") from None
            if isinstance(doc, dict) and doc.get("format") == DICT_FORMAT:
                return SWTDataset.from_dict(doc)
            return load_summary(data if path is None else path, metadata, name=name)
        stream.seek(0)
        reader = TableReader(text_lines(stream))
        try:
            reader.read_head()
        except LogFormatError as exc:
            raise LogFormatError(f"{label}: {exc}") from None
        is_log = any(parse_header_field(h)[0] == "time" for h in reader.header)
        target = stream if path is None else path
        if is_log:
            return load_log(target, metadata, name=name, **log_options)
        return load_summary(target, metadata, name=name)


def write_log(
    path: str | os.PathLike[str],
    t: np.ndarray,
    F: np.ndarray,
    T: np.ndarray,
    z: np.ndarray,
    metadata: Mapping[str, Any] | TestConditions,
    *,
    Fy: np.ndarray | None = None,
    normal_force: np.ndarray | None = None,
    slip: np.ndarray | None = None,
    units: Mapping[str, str] | None = None,
    sidecar: bool = True,
    precision: int = 17,
) -> Path:
    """Write a log: ``# key: value`` metadata lines, header, rows; plus a JSON sidecar.

    Inputs in SI: t (s), F (N), T (Nm), z (m), Fy (N, the lateral force, + against the side
    slip), normal_force (N), slip (-). ``units`` picks file
    units per column, e.g. ``{"sinkage": "mm", "time": "ms"}``. Metadata is validated first
    and written with canonical keys (W, slip, omega, ...) in SI. Returns the CSV path.
    """
    raw = metadata.to_dict() if isinstance(metadata, TestConditions) else dict(metadata)
    meta = merge_metadata([("metadata", raw)])
    flat = {k: v for k, v in meta.conditions.to_dict().items() if v is not None}
    flat.update(meta.provenance)
    columns = {"time": t, "drawbar_pull": F, "torque": T, "sinkage": z}
    if Fy is not None:
        columns["lateral_force"] = Fy
    if normal_force is not None:
        columns["normal_force"] = normal_force
    if slip is not None:
        columns["slip"] = slip
    out = Path(path)
    out.write_bytes(format_log(columns, flat, units, precision).encode("utf-8"))
    if sidecar:
        out.with_suffix(".json").write_text(json.dumps(flat, indent=2) + "\n", encoding="utf-8")
    return out
