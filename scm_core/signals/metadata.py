"""Metadata parsing: ``# key: value`` lines, JSON sidecars and caller dicts.

Keys are case-insensitive; spaces and hyphens read as underscores; a unit may be given in the
key (``wheel_radius [mm]: 125``) or after the value (``wheel_radius: 125 mm``). Bare numbers are
SI. Known keys become :class:`TestConditions` fields; any other key is free provenance.
"""

import json
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from scm_core.validation_text import quoted

from .conditions import TestConditions, make_conditions
from .errors import LogFormatError
from .units import parse_value

#: condition field -> (quantity, accepted metadata keys, lower-case)
CONDITION_KEYS: dict[str, tuple[str, tuple[str, ...]]] = {
    "W": ("force", ("w", "normal_load", "load", "wheel_load", "vertical_load")),
    "slip": ("slip", ("slip", "slip_ratio")),
    "slip_symmetric": ("slip", ("slip_symmetric", "slip_lab")),
    "slip_convention": ("text", ("slip_convention", "slip_definition")),
    "omega": ("angular_velocity", ("omega", "angular_velocity", "wheel_angular_velocity")),
    "carriage_speed": ("speed", ("carriage_speed", "v", "speed", "translational_speed")),
    "rim_speed": ("speed", ("rim_speed", "v_rim", "wheel_speed", "circumferential_speed")),
    "R": ("length", ("r", "wheel_radius", "radius")),
    "b": ("length", ("b", "wheel_width", "width")),
    "n_grousers": ("count", ("n_grousers", "grousers", "grouser_count", "n_g")),
    "grouser_height": ("length", ("grouser_height", "h_g", "grouser_depth")),
    "slip_angle": (
        "angle",
        ("slip_angle", "slip_angle_deg", "beta", "steering_angle", "yaw_angle"),
    ),
}
_ALIAS = {alias: name for name, (_, aliases) in CONDITION_KEYS.items() for alias in aliases}
_KEY_UNIT = re.compile(r"^(?P<key>[^\[\]]*?)\s*\[(?P<unit>[^\[\]]*)\]\s*$")


@dataclass(frozen=True)
class Metadata:
    """Parsed metadata: validated conditions plus free provenance fields (soil, date, ...)."""

    conditions: TestConditions
    provenance: dict[str, Any] = field(default_factory=dict)


def normalise_key(key: str) -> str:
    """Lower-case ``key`` with spaces and hyphens as underscores."""
    return re.sub(r"[\s\-]+", "_", key.strip()).lower()


def parse_metadata_lines(lines: Iterable[tuple[int, str]]) -> dict[str, str]:
    """Parse ``(line_number, "# key: value")`` pairs; comment lines without a colon are skipped."""
    out: dict[str, str] = {}
    for lineno, line in lines:
        body = line.lstrip()[1:].strip()
        if ":" not in body:
            continue
        key, value = body.split(":", 1)
        key = key.strip()
        if not key:
            raise LogFormatError(f"line {lineno}: metadata line has no key before ':'")
        if key in out:
            raise LogFormatError(f"line {lineno}: metadata key {quoted(key)} given twice")
        out[key] = value.strip()
    return out


def _flatten(raw: Mapping[str, Any]) -> dict[str, Any]:
    """Accept ``{"conditions": {...}, "provenance": {...}}`` as well as a flat dict."""
    flat: dict[str, Any] = {}
    for key, value in raw.items():
        if key in ("conditions", "provenance") and isinstance(value, Mapping):
            flat.update(value)
        else:
            flat[key] = value
    return flat


def _condition_value(name: str, value: Any, unit: str | None, where: str) -> float | int | str:
    quantity = CONDITION_KEYS[name][0]
    if quantity == "text":
        if not isinstance(value, str):
            raise LogFormatError(f"{where}: expected a name, got {quoted(value)}")
        return value.strip()
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise LogFormatError(f"{where}: expected a number, got {quoted(value)}")
    if isinstance(value, str):
        number = parse_value(value, quantity, where, default_unit=unit)
    else:
        text = repr(float(value)) if math.isfinite(value) else str(value)
        number = parse_value(text, quantity, where, default_unit=unit)
    if quantity == "count":
        if number != int(number):
            raise LogFormatError(f"{where}: expected a whole number, got {quoted(value)}")
        return int(number)
    return number


def parse_metadata_source(raw: Mapping[str, Any], source: str) -> tuple[dict, dict]:
    """Split one metadata source into (condition values in SI, provenance)."""
    conditions: dict[str, float | int] = {}
    provenance: dict[str, Any] = {}
    for raw_key, value in _flatten(raw).items():
        m = _KEY_UNIT.match(str(raw_key))
        key, unit = (m.group("key"), m.group("unit")) if m else (str(raw_key), None)
        norm = normalise_key(key)
        name = _ALIAS.get(norm)
        where = f"{source} {quoted(raw_key)}"
        if name is None:
            try:
                json.dumps(value)
            except (TypeError, ValueError):
                raise LogFormatError(
                    f"{where}: value {quoted(value)} is not JSON-compatible"
                ) from None
            provenance[norm] = value
            continue
        if value is None or value == "":
            continue
        if name in conditions:
            raise LogFormatError(f"{where}: condition '{name}' given twice in the {source}")
        conditions[name] = _condition_value(name, value, unit, where)
    return conditions, provenance


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return str(a) == str(b)
    return math.isclose(a, b, rel_tol=1e-9)


def merge_metadata(sources: Iterable[tuple[str, Mapping[str, Any]]]) -> Metadata:
    """Merge metadata sources (name, dict), later sources overriding earlier provenance.

    A condition given in two sources must agree (relative tolerance 1e-9), else it is refused.
    """
    conditions: dict[str, float | int] = {}
    origin: dict[str, str] = {}
    provenance: dict[str, Any] = {}
    for source, raw in sources:
        if not raw:
            continue
        cond, prov = parse_metadata_source(raw, source)
        for key, value in cond.items():
            if key in conditions and not _same(conditions[key], value):
                raise LogFormatError(
                    f"metadata '{key}' conflicts: {quoted(conditions[key])} in the {origin[key]}, "
                    f"{quoted(value)} in the {source}"
                )
            conditions[key] = value
            origin[key] = source
        provenance.update(prov)
    return Metadata(make_conditions(conditions), provenance)
