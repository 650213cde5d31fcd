"""Summary-form SWT datasets: steady means and standard deviations per response (no series).

JSON::

    {"name": "run 7",                                   (optional)
     "conditions": {"slip": 0.2, "normal_load": "315 N", "soil": "WF34", ...},
     "provenance": {...},                               (optional, free)
     "responses": {"F": {"mean": 20.1, "sd": 1.2, "unit": "N"},
                   "T": {"mean": 5.3, "sd": 0.4, "unit": "Nm"},
                   "z": {"mean": 12.0, "sd": 1.0, "unit": "mm"},
                   "Fy": {"mean": 8.2, "sd": 0.5, "unit": "N"}},   (a steered wheel)
     "n_trials": 3}

CSV, one row per response, conditions and ``n_trials`` as ``# key: value`` lines::

    # slip: 0.2
    # normal_load: 315 N
    # n_trials: 3
    response,mean,sd,unit
    F,20.1,1.2,N

or one row per trial (no ``time`` column; mean and sd, ddof=1, across >= 2 rows)::

    # slip: 0.2
    # normal_load: 315 N
    trial,drawbar_pull [N],torque [Nm],sinkage [mm]
    1,20.3,5.2,11.8

Missing ``unit`` means SI, but for the lateral force ``Fy`` (refused without one). Standard
error = sd / sqrt(n_trials).
For users: docs/data-formats.md (both formats, every metadata key, examples).
"""

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from scm_core.validation_text import quoted

from .csvtext import CsvTable, split_table
from .errors import LogFormatError
from .logformat import (
    COLUMNS,
    cells_to_float,
    check_plausible,
    column_name,
    no_unit,
    parse_header_field,
)
from .metadata import Metadata, merge_metadata, parse_metadata_lines
from .processing import ResponseStat
from .responses import COLUMN_OF, RESPONSE_KEYS, response
from .units import SI_UNIT, plausible_message, unit_factor

#: response key -> log column it is measured as
RESPONSE_COLUMNS = COLUMN_OF
_COLUMN_RESPONSE = {c: k for k, c in RESPONSE_COLUMNS.items()}
_TOP_KEYS = ("name", "conditions", "provenance", "responses", "n_trials")
#: largest summary or JSON dataset file read (a summary of many trials is a few kB; only
#: time-series logs are large, and those are read in chunks)
MAX_SUMMARY_BYTES = 4 * 1024 * 1024


@dataclass(frozen=True)
class Summary:
    """A parsed summary: metadata, SI statistics per response F, T, z, Fy, trial count, name."""

    metadata: Metadata
    stats: dict[str, ResponseStat]
    n_trials: int
    name: str | None


def response_key(name: str) -> str | None:
    """``F``/``drawbar_pull`` -> ``F``, ``T``/``torque`` -> ``T``, ``z``/``sinkage`` -> ``z``,
    ``Fy``/``lateral_force``/``side_force`` -> ``Fy``."""
    return _COLUMN_RESPONSE.get(column_name(name) or "")


def _unknown(at: str) -> LogFormatError:
    return LogFormatError(f"{at}: unknown response (accepted: {', '.join(RESPONSE_KEYS)})")


def _unit(key: str, given: Any, at: str) -> str:
    """The unit of a summary's response ``key`` as given (None: SI, but for a response that
    must state its unit)."""
    if given is not None and not isinstance(given, str):
        raise LogFormatError(f"{at}: unit must be a string, got {quoted(given)}")
    if given is not None:
        return given
    r = response(key)
    if r.unit_required:
        raise LogFormatError(
            f"{at}: {r.column} has no unit; give it (e.g. {quoted(SI_UNIT[r.quantity])})"
        )
    return SI_UNIT[r.quantity]


def _stat(key: str, mean: float, sd: float, n_trials: int, unit: str, where: str) -> ResponseStat:
    quantity = COLUMNS[RESPONSE_COLUMNS[key]][0]
    factor = unit_factor(quantity, unit, where)
    if not (math.isfinite(mean) and math.isfinite(sd)):
        raise LogFormatError(f"{where}: mean and sd must be finite (got {mean!r}, {sd!r})")
    if sd < 0:
        raise LogFormatError(f"{where}: sd = {sd!r} {unit} is negative")
    for label, value in (("mean", mean * factor), ("sd", sd * factor)):
        problem = plausible_message(quantity, value)
        if problem is not None:
            raise LogFormatError(f"{where}: {label} {problem}")
    se = sd / math.sqrt(n_trials)
    return ResponseStat(mean * factor, se * factor, sd * factor, float(n_trials))


def _check_complete(stats: Mapping[str, Any], where: str) -> None:
    if not stats:
        named = ", ".join(f"{k} ({c})" for k, c in RESPONSE_COLUMNS.items())
        raise LogFormatError(f"{where}: no response; give at least one of {named}")


def _n_trials(value: Any, where: str) -> int:
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise LogFormatError(f"{where}: n_trials {quoted(value)} is not a number") from None
    if isinstance(value, bool) or not isinstance(value, int | float) or value != int(value):
        raise LogFormatError(f"{where}: n_trials must be a whole number, got {quoted(value)}")
    if value < 1:
        raise LogFormatError(f"{where}: n_trials must be >= 1, got {quoted(value)}")
    return int(value)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise LogFormatError(f"{where}: expected a number, got {quoted(value)}")
    return float(value)


def parse_summary_json(
    data: bytes | str | Mapping[str, Any], extra_metadata: Mapping[str, Any] | None = None
) -> Summary:
    """Parse a JSON summary (text or already-decoded dict) into SI statistics."""
    where = "summary JSON"
    if isinstance(data, Mapping):
        doc: Any = data
    else:
        try:
            doc = json.loads(data.decode("utf-8-sig") if isinstance(data, bytes) else data)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise LogFormatError(f"{where}: not valid JSON ({exc})") from None
    if not isinstance(doc, Mapping):
        raise LogFormatError(f"{where}: top level must be an object")
    unknown = [k for k in doc if k not in _TOP_KEYS]
    if unknown:
        raise LogFormatError(f"{where}: unknown key(s) {unknown} (accepted: {list(_TOP_KEYS)})")
    for key in ("conditions", "responses", "n_trials"):
        if key not in doc:
            raise LogFormatError(f"{where}: missing {quoted(key)}")
    n_trials = _n_trials(doc["n_trials"], where)
    responses = doc["responses"]
    if not isinstance(responses, Mapping):
        raise LogFormatError(f"{where}: 'responses' must be an object")
    stats: dict[str, ResponseStat] = {}
    for raw_key, entry in responses.items():
        key = response_key(raw_key)
        at = f"{where} response {quoted(raw_key)}"
        if key is None:
            raise _unknown(at)
        if key in stats:
            raise LogFormatError(f"{at}: response {key} given twice")
        if not isinstance(entry, Mapping) or "mean" not in entry or "sd" not in entry:
            raise LogFormatError(f"{at}: needs an object with 'mean' and 'sd'")
        extra = set(entry) - {"mean", "sd", "unit"}
        if extra:
            raise LogFormatError(f"{at}: unknown field(s) {sorted(extra)}")
        unit = _unit(key, entry.get("unit"), at)
        mean, sd = _number(entry["mean"], f"{at} mean"), _number(entry["sd"], f"{at} sd")
        stats[key] = _stat(key, mean, sd, n_trials, unit, at)
    _check_complete(stats, where)
    for key in ("conditions", "provenance"):
        if not isinstance(doc.get(key, {}), Mapping):
            raise LogFormatError(f"{where}: {quoted(key)} must be an object")
    metadata = merge_metadata(
        [
            ("summary conditions", doc["conditions"]),
            ("summary provenance", doc.get("provenance", {})),
            ("metadata", extra_metadata or {}),
        ]
    )
    name = doc.get("name")
    return Summary(metadata, stats, n_trials, None if name is None else str(name))


def _per_response(table: CsvTable, n_trials: int, where: str) -> dict[str, ResponseStat]:
    cols = {h.strip().lower(): i for i, h in enumerate(table.header)}
    sd_col = next(
        (cols[k] for k in ("sd", "std", "stdev", "standard_deviation") if k in cols), None
    )
    if "mean" not in cols or sd_col is None:
        raise LogFormatError(
            f"line {table.header_line}: summary CSV needs columns response, mean, sd[, unit] "
            f"(header has: {', '.join(table.header)})"
        )
    stats: dict[str, ResponseStat] = {}
    for row, line in zip(table.rows, table.row_lines, strict=True):
        raw_key = row[cols["response"]].strip()
        key = response_key(raw_key)
        at = f"line {line}, response {quoted(raw_key)}"
        if key is None:
            raise _unknown(at)
        if key in stats:
            raise LogFormatError(f"{at}: response {key} given twice")
        mean = float(cells_to_float([row[cols["mean"]]], [line], "mean")[0])
        sd = float(cells_to_float([row[sd_col]], [line], table.header[sd_col])[0])
        unit = _unit(key, (row[cols["unit"]].strip() if "unit" in cols else "") or None, at)
        stats[key] = _stat(key, mean, sd, n_trials, unit, at)
    _check_complete(stats, where)
    return stats


def _per_trial(table: CsvTable, where: str) -> tuple[dict[str, ResponseStat], int]:
    found: dict[str, tuple[int, str]] = {}
    for i, field in enumerate(table.header):
        name, unit = parse_header_field(field)
        if name == "time":
            raise LogFormatError(
                f"line {table.header_line}: {quoted(field)} column: this is a time-series log, "
                "not a summary"
            )
        key = _COLUMN_RESPONSE.get(name or "")
        if key is None:
            continue
        if unit is None:
            raise LogFormatError(f"line {table.header_line}: {no_unit(field, name, i)}")
        if key in found:
            raise LogFormatError(f"line {table.header_line}: duplicate column for {key}")
        found[key] = (i, unit)
    _check_complete(found, f"{where} (header line {table.header_line})")
    n = len(table.rows)
    if n < 2:
        raise LogFormatError(f"{where}: {n} trial row(s); need at least 2 to estimate an sd")
    stats = {}
    for key, (i, unit) in found.items():
        cells = [r[i] for r in table.rows]
        x = cells_to_float(cells, table.row_lines, table.header[i])
        quantity = COLUMNS[RESPONSE_COLUMNS[key]][0]
        factor = unit_factor(quantity, unit, f"{where} column {quoted(table.header[i])}")
        check_plausible(x * factor, quantity, cells, table.row_lines, table.header[i])
        stats[key] = _stat(key, float(x.mean()), float(np.std(x, ddof=1)), n, unit, where)
    return stats, n


def parse_summary_csv(
    data: bytes | str, extra_metadata: Mapping[str, Any] | None = None
) -> Summary:
    """Parse a per-response or per-trial summary CSV into SI statistics."""
    where = "summary CSV"
    table = split_table(data)
    meta = parse_metadata_lines(table.metadata_lines)
    n_key = next((k for k in meta if k.strip().lower().replace(" ", "_") == "n_trials"), None)
    n_meta = meta.pop(n_key) if n_key else None
    name = meta.pop("name", None)
    if not table.rows:
        raise LogFormatError(f"no data rows after the header (line {table.header_line})")
    if "response" in (h.strip().lower() for h in table.header):
        if n_meta is None:
            raise LogFormatError(f"{where}: missing '# n_trials: <count>' metadata line")
        n_trials = _n_trials(n_meta, where)
        stats = _per_response(table, n_trials, where)
    else:
        stats, n_trials = _per_trial(table, where)
        if n_meta is not None and _n_trials(n_meta, where) != n_trials:
            raise LogFormatError(f"{where}: n_trials = {n_meta} but {n_trials} trial rows")
    metadata = merge_metadata([("file", meta), ("metadata", extra_metadata or {})])
    return Summary(metadata, stats, n_trials, name)
