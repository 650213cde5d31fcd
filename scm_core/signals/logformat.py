"""Time-series SWT log format: header/column parsing to SI arrays, and the writer (text only).

Header fields are ``name [unit]``; see :data:`COLUMNS` for names, aliases and quantities.
Columns with unknown names are ignored (they need no unit). Known columns without a unit in
brackets are refused, as are duplicate columns, empty, non-numeric or non-finite cells.
"""

import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .csvtext import CsvTable, split_table
from .errors import LogFormatError
from .metadata import CONDITION_KEYS, parse_metadata_lines
from .units import SI_UNIT, UNITS, unit_factor

#: canonical column -> (quantity, lower-case aliases)
COLUMNS: dict[str, tuple[str, tuple[str, ...]]] = {
    "time": ("time", ("time",)),
    "drawbar_pull": ("force", ("drawbar_pull", "drawbar", "drawbar_force", "dp", "f", "fx")),
    "torque": ("torque", ("torque", "wheel_torque", "driving_torque", "m", "my")),
    "sinkage": ("length", ("sinkage", "z", "wheel_sinkage")),
    "normal_force": ("force", ("normal_force", "fz", "fn", "normal_load")),
    "slip": ("slip", ("slip", "slip_ratio", "s")),
}
REQUIRED_COLUMNS = ("time",)
#: measured responses: a log carries at least one of them
RESPONSE_COLUMNS = ("drawbar_pull", "torque", "sinkage")
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


def _parse_header(table: CsvTable) -> dict[str, tuple[int, str]]:
    """Map canonical column -> (field index, unit)."""
    found: dict[str, tuple[int, str]] = {}
    seen: dict[str, int] = {}
    line = table.header_line
    for i, field in enumerate(table.header):
        if field in seen:
            raise LogFormatError(
                f"line {line}: duplicate column '{field}' (columns {seen[field] + 1} and {i + 1})"
            )
        seen[field] = i
        name, unit = parse_header_field(field)
        if name is None:
            continue
        if unit is None:
            quantity = COLUMNS[name][0]
            raise LogFormatError(
                f"line {line}: column '{field}' (column {i + 1}) has no unit in brackets, "
                f"e.g. '{field} [{SI_UNIT[quantity]}]'"
            )
        if name in found:
            other = table.header[found[name][0]]
            raise LogFormatError(
                f"line {line}: duplicate column '{name}': '{other}' (column {found[name][0] + 1})"
                f" and '{field}' (column {i + 1})"
            )
        found[name] = (i, unit)
    missing = [c for c in REQUIRED_COLUMNS if c not in found]
    if missing or not any(c in found for c in RESPONSE_COLUMNS):
        raise LogFormatError(
            f"line {line}: missing required column(s) "
            f"{', '.join(missing) or 'drawbar_pull, torque or sinkage'} (header has: "
            f"{', '.join(table.header)}; required: time and at least one of drawbar_pull, "
            "torque, sinkage, or t and F, T, z, each with its unit in brackets)"
        )
    return found


def cells_to_float(cells: list[str], rows: list[int], header: str) -> np.ndarray:
    """Convert one column's cells to float, naming the first bad cell by line and column."""
    try:
        if any("_" in c for c in cells):
            raise ValueError
        values = np.array(cells, dtype=object).astype(np.float64)
    except ValueError:
        for cell, line in zip(cells, rows, strict=True):
            if not cell.strip():
                raise LogFormatError(f"line {line}, column '{header}': empty cell") from None
            try:
                if "_" in cell:
                    raise ValueError
                float(cell)
            except ValueError:
                raise LogFormatError(
                    f"line {line}, column '{header}': '{cell.strip()}' is not a number"
                ) from None
        raise  # pragma: no cover - numpy and float() disagree
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = int(bad[0])
        raise LogFormatError(
            f"line {rows[k]}, column '{header}': non-finite value '{cells[k].strip()}'"
        )
    return values


def parse_log_text(data: bytes | str) -> LogTable:
    """Parse log text into SI columns (s, N, Nm, m, -) with per-sample file line numbers."""
    table = split_table(data)
    metadata = parse_metadata_lines(table.metadata_lines)
    found = _parse_header(table)
    if not table.rows:
        raise LogFormatError(f"no data rows after the header (line {table.header_line})")
    columns: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    for name, (index, unit) in found.items():
        header = table.header[index]
        where = f"line {table.header_line}, column '{header}'"
        factor = unit_factor(COLUMNS[name][0], unit, where)
        cells = [row[index] for row in table.rows]
        columns[name] = cells_to_float(cells, table.row_lines, header) * factor
        units[name] = unit
    return LogTable(columns, np.asarray(table.row_lines), metadata, units)


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

    ``columns`` maps canonical names (time, drawbar_pull, torque, sinkage[, normal_force, slip])
    to SI arrays; ``units`` optionally picks file units per column (e.g. ``{"sinkage": "mm"}``).
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
