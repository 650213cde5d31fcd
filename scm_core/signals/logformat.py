"""Time-series SWT log format: header/column parsing to SI arrays, and the writer (text only).

Header fields are ``name [unit]``; see :data:`COLUMNS` for names, aliases and quantities.
Columns with unknown names are ignored (they need no unit). Known columns without a unit in
brackets are refused, as are duplicate columns, empty, non-numeric or non-finite cells.
For users: docs/data-formats.md (both formats, every metadata key, examples).
"""

import io
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, BinaryIO

import numpy as np

from scm_core.validation_text import quoted

from .csvtext import CanonicalDigest, TableReader, text_lines
from .errors import LogFormatError
from .metadata import CONDITION_KEYS, parse_metadata_lines
from .responses import COLUMN_OF
from .units import PLAUSIBLE_MAX, SI_UNIT, UNITS, plausible_message, unit_factor

#: canonical column -> (quantity, lower-case aliases)
COLUMNS: dict[str, tuple[str, tuple[str, ...]]] = {
    "time": ("time", ("time",)),
    "drawbar_pull": ("force", ("drawbar_pull", "drawbar", "drawbar_force", "dp", "f", "fx")),
    "torque": ("torque", ("torque", "wheel_torque", "driving_torque", "m", "my")),
    "sinkage": ("length", ("sinkage", "z", "wheel_sinkage")),
    # along the axle, + against the side slip (examples/cmu_steering/README.md)
    "lateral_force": ("force", ("lateral_force", "fy", "side_force")),
    "normal_force": ("force", ("normal_force", "fz", "fn", "normal_load")),
    "slip": ("slip", ("slip", "slip_ratio", "s")),
}
REQUIRED_COLUMNS = ("time",)
#: measured responses: a log carries at least one of them
RESPONSE_COLUMNS = tuple(COLUMN_OF.values())
#: case-sensitive single-letter aliases that differ only by case
_EXACT = {"t": "time", "T": "torque"}
_ALIASES = {alias: name for name, (_, aliases) in COLUMNS.items() for alias in aliases}
_HEADER = re.compile(r"^(?P<name>[^\[\]]*?)\s*\[(?P<unit>[^\[\]]*)\]$")


@dataclass(frozen=True)
class LogTable:
    """A parsed log: SI columns, the file line of each sample, raw metadata and column units."""

    columns: dict[str, np.ndarray]
    lines: np.ndarray
    metadata: dict[str, str]
    units: dict[str, str]


def column_name(name: str) -> str | None:
    """Canonical column for a header name or alias (``F``, ``T``, ``z``, ``t``), else None."""
    name = name.strip()
    if name in _EXACT:
        return _EXACT[name]
    return _ALIASES.get(re.sub(r"[\s\-]+", "_", name).lower())


def parse_header_field(field: str) -> tuple[str | None, str | None]:
    """``"sinkage [mm]"`` -> ("sinkage", "mm"); unknown names give None, no brackets unit None."""
    m = _HEADER.match(field.strip())
    return column_name(m.group("name") if m else field), (m.group("unit") if m else None)


def _parse_header(header: list[str], line: int) -> dict[str, tuple[int, str]]:
    """Map canonical column -> (field index, unit)."""
    found: dict[str, tuple[int, str]] = {}
    seen: dict[str, int] = {}
    for i, field in enumerate(header):
        if field in seen:
            raise LogFormatError(
                f"line {line}: duplicate column {quoted(field)} "
                f"(columns {seen[field] + 1} and {i + 1})"
            )
        seen[field] = i
        name, unit = parse_header_field(field)
        if name is None:
            continue
        if unit is None:
            raise LogFormatError(f"line {line}: {no_unit(field, name, i)}")
        if name in found:
            other = header[found[name][0]]
            raise LogFormatError(
                f"line {line}: duplicate column '{name}': {quoted(other)} "
                f"(column {found[name][0] + 1}) and {quoted(field)} (column {i + 1})"
            )
        found[name] = (i, unit)
    missing = [c for c in REQUIRED_COLUMNS if c not in found]
    if missing or not any(c in found for c in RESPONSE_COLUMNS):
        columns = ", ".join(RESPONSE_COLUMNS)
        lacking = ", ".join(missing) or one_of(RESPONSE_COLUMNS)
        raise LogFormatError(
            f"line {line}: missing required column(s) {lacking} "
            f"(header has: {quoted(', '.join(header), 200)}; required: time and at least one "
            f"of {columns}, or t and {', '.join(COLUMN_OF)}, each with its unit in brackets)"
        )
    return found


def one_of(names: tuple[str, ...]) -> str:
    """``a, b or c``."""
    return " or ".join((", ".join(names[:-1]), names[-1])) if len(names) > 1 else names[0]


def no_unit(field: str, name: str, index: int) -> str:
    """Why the header ``field`` (canonical column ``name``, at ``index``) is refused without
    its unit: the field as written, the column it reads as, an example with the SI unit."""
    known = "" if field.strip() == name else f": {name}"
    example = quoted(f"{field.strip()} [{SI_UNIT[COLUMNS[name][0]]}]")
    return (
        f"column {quoted(field)} (column {index + 1}{known}) has no unit in brackets, "
        f"e.g. {example}"
    )


def cells_to_float(cells: list[str], rows: list[int], header: str) -> np.ndarray:
    """Convert one column's cells to float, naming the first bad cell by line and column."""
    try:
        if any("_" in c for c in cells):
            raise ValueError
        values = np.array(cells, dtype=object).astype(np.float64)
    except ValueError:
        for cell, line in zip(cells, rows, strict=True):
            if not cell.strip():
                raise LogFormatError(f"line {line}, column {quoted(header)}: empty cell") from None
            try:
                if "_" in cell:
                    raise ValueError
                float(cell)
            except ValueError:
                raise LogFormatError(
                    f"line {line}, column {quoted(header)}: {quoted(cell.strip())} is not a number"
                ) from None
        raise  # pragma: no cover - numpy and float() disagree
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = int(bad[0])
        raise LogFormatError(
            f"line {rows[k]}, column {quoted(header)}: non-finite value {quoted(cells[k].strip())}"
        )
    return values


def check_plausible(
    values: np.ndarray, quantity: str, cells: list[str], rows: list[int], header: str
) -> None:
    """Refuse SI ``values`` beyond :data:`~.units.PLAUSIBLE_MAX`, naming the first bad cell."""
    bad = np.flatnonzero(np.abs(values) > PLAUSIBLE_MAX[quantity])
    if bad.size:
        k = int(bad[0])
        problem = plausible_message(quantity, float(values[k]))
        raise LogFormatError(
            f"line {rows[k]}, column {quoted(header)}: {quoted(cells[k].strip())} is {problem}"
        )


class _Column:
    """A growing 1-D array written chunk by chunk: one large allocation (returned to the
    system when freed) instead of many chunk arrays to concatenate, which would fragment the
    heap and double the peak."""

    def __init__(self, capacity: int, dtype: type) -> None:
        self._data = np.empty(max(capacity, 1), dtype=dtype)
        self._n = 0

    def extend(self, values: np.ndarray) -> None:
        end = self._n + values.size
        if end > self._data.size:
            grown = np.empty(max(end, 2 * self._data.size), dtype=self._data.dtype)
            grown[: self._n] = self._data[: self._n]
            self._data = grown
        self._data[self._n : end] = values
        self._n = end

    def values(self) -> np.ndarray:
        return self._data[: self._n]


def _remaining_bytes(stream: BinaryIO) -> int:
    """Bytes from the position to the end of a seekable stream (0 when unknown)."""
    try:
        here = stream.tell()
        end = stream.seek(0, io.SEEK_END)
        stream.seek(here)
    except (OSError, ValueError, AttributeError):
        return 0
    return max(end - here, 0)


def _fast_chunk(
    lines: list[str],
    reader: TableReader,
    found: dict[str, tuple[int, str]],
    factors: dict[str, float],
) -> dict[str, np.ndarray] | None:
    """SI columns of a chunk read by numpy's C parser, or None when the chunk needs the
    checked path: quotes, a ragged row, a cell numpy cannot read, or a value to refuse."""
    delimiter = reader.delimiter
    width = len(reader.header) - 1
    if any(('"' in line) or line.count(delimiter) != width for line in lines):
        return None
    names = list(found)
    try:
        table = np.loadtxt(
            lines,
            delimiter=delimiter,
            usecols=[found[name][0] for name in names],
            dtype=np.float64,
            comments=None,
            ndmin=2,
        )
    except ValueError:
        return None
    out = {}
    for k, name in enumerate(names):
        values = table[:, k] * factors[name]
        bound = PLAUSIBLE_MAX[COLUMNS[name][0]]
        if not (np.all(np.isfinite(values)) and np.all(np.abs(values) <= bound)):
            return None
        out[name] = values
    return out


def _checked_chunk(
    lines: list[str],
    numbers: list[int],
    reader: TableReader,
    found: dict[str, tuple[int, str]],
    factors: dict[str, float],
) -> dict[str, np.ndarray]:
    """SI columns of a chunk, cell by cell, naming the line and column of the first bad cell."""
    rows = reader.split_rows(lines, numbers)
    out = {}
    for name, (index, _) in found.items():
        header = reader.header[index]
        cells = [row[index] for row in rows]
        values = cells_to_float(cells, numbers, header) * factors[name]
        check_plausible(values, COLUMNS[name][0], cells, numbers, header)
        out[name] = values
    return out


def parse_log_stream(stream: BinaryIO, digest: CanonicalDigest | None = None) -> LogTable:
    """Parse a log from a binary stream into SI columns (s, N, Nm, m, -) with per-sample file
    line numbers, in chunks of rows (memory: the columns plus one chunk of cells). Every
    physical line also goes to ``digest`` (the content hash of the canonical text)."""
    reader = TableReader(text_lines(stream), digest)
    reader.read_head()
    metadata = parse_metadata_lines(reader.metadata_lines)
    found = _parse_header(reader.header, reader.header_line)
    factors = {}
    for name, (index, unit) in found.items():
        where = f"line {reader.header_line}, column {quoted(reader.header[index])}"
        factors[name] = unit_factor(COLUMNS[name][0], unit, where)
    size = _remaining_bytes(stream)
    columns: dict[str, _Column] = {}
    line_numbers: _Column | None = None
    for lines, numbers in reader.line_chunks():
        values = _fast_chunk(lines, reader, found, factors)
        if values is None:  # something to report (or quoting): the exact, cell-by-cell path
            values = _checked_chunk(lines, numbers, reader, found, factors)
        if line_numbers is None:  # size the columns once: file size / mean line length
            per_line = sum(map(len, lines)) / len(lines) + 1.0
            expected = int(1.05 * size / per_line) + len(lines) if size else len(lines)
            columns = {name: _Column(expected, np.float64) for name in found}
            line_numbers = _Column(expected, np.int64)
        for name in found:
            columns[name].extend(values[name])
        line_numbers.extend(np.asarray(numbers, dtype=np.int64))
    if line_numbers is None:
        raise LogFormatError(f"no data rows after the header (line {reader.header_line})")
    units = {name: unit for name, (_, unit) in found.items()}
    arrays = {name: column.values() for name, column in columns.items()}
    return LogTable(arrays, line_numbers.values(), metadata, units)


def parse_log_text(data: bytes | str) -> LogTable:
    """Parse log text into SI columns (s, N, Nm, m, -) with per-sample file line numbers."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    return parse_log_stream(io.BytesIO(raw))


def _meta_value(key: str, value: Any) -> str:
    if key in CONDITION_KEYS and CONDITION_KEYS[key][0] != "text":
        unit = SI_UNIT[CONDITION_KEYS[key][0]]
        number = repr(int(value)) if key == "n_grousers" else repr(float(value))
        return f"{number} {unit}".rstrip() if unit not in ("-", "") else number
    text = value if isinstance(value, str) else json.dumps(value)
    return " ".join(text.split())  # one line


def format_log(
    columns: Mapping[str, np.ndarray],
    metadata: Mapping[str, Any],
    units: Mapping[str, str] | None = None,
    precision: int = 17,
) -> str:
    """Log text: ``# key: value`` lines, a header with units, then one row per sample.

    ``columns`` maps canonical names (time and the :data:`COLUMNS` a log carries, e.g.
    drawbar_pull, torque, sinkage, lateral_force, normal_force, slip) to SI arrays; ``units``
    optionally picks file units per column (e.g. ``{"sinkage": "mm"}``).
    ``precision`` significant digits (17 round-trips a float64 exactly).
    """
    units = dict(units or {})
    names = [c for c in COLUMNS if c in columns]
    unknown = set(columns) - set(names)
    if unknown:
        raise ValueError(f"unknown column(s) {sorted(unknown)}; known: {list(COLUMNS)}")
    data = []
    header = []
    for name in names:
        quantity = COLUMNS[name][0]
        unit = units.pop(name, SI_UNIT[quantity])
        if unit not in UNITS[quantity]:
            raise ValueError(f"unit '{unit}' for {name}; accepted: {list(UNITS[quantity])}")
        data.append(np.asarray(columns[name], dtype=np.float64) / UNITS[quantity][unit])
        header.append(f"{name} [{unit}]")
    if units:
        raise ValueError(f"units given for absent column(s) {sorted(units)}")
    lengths = {len(d) for d in data}
    if len(lengths) != 1:
        raise ValueError(f"columns differ in length: {sorted(lengths)}")
    lines = [f"# {key}: {_meta_value(key, value)}" for key, value in metadata.items()]
    lines.append(",".join(header))
    matrix = np.column_stack(data)
    if not np.all(np.isfinite(matrix)):
        raise ValueError("columns contain NaN or inf")
    fmt = f"%.{int(precision)}g"
    lines.extend(",".join(fmt % v for v in row) for row in matrix.tolist())
    return "\n".join(lines) + "\n"
