"""Unit tables and conversion to SI for SWT columns and metadata values.

Lookup is case-insensitive within one quantity (``NM`` and ``nm`` both mean newton metre for a
torque); spaces and the middle dot act as multiplication signs (``N m`` == ``N*m``).
"""

import math
import re

from scm_core.validation_text import quoted

from .errors import LogFormatError

#: quantity -> {canonical unit spelling: factor to SI}
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0},
    "force": {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605, "kgf": 9.80665},
    "torque": {
        "Nm": 1.0,
        "N*m": 1.0,
        "N.m": 1.0,
        "kNm": 1e3,
        "kN*m": 1e3,
        "Nmm": 1e-3,
        "N*mm": 1e-3,
        "N.mm": 1e-3,
        "lbf*ft": 1.3558179483314004,
        "ft*lbf": 1.3558179483314004,
        "lbf.ft": 1.3558179483314004,
    },
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254},
    "slip": {"-": 1.0, "": 1.0, "1": 1.0, "%": 1e-2},
    "angular_velocity": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "deg/s": math.pi / 180.0},
    "speed": {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3, "m/min": 1.0 / 60.0, "km/h": 1.0 / 3.6},
    "count": {"": 1.0, "-": 1.0},
    # angles are kept in degrees, as the case files give phi and the labs give slip angles
    "angle": {"deg": 1.0, "°": 1.0, "degree": 1.0, "degrees": 1.0, "rad": 180.0 / math.pi},
}

#: SI unit written for each quantity.
SI_UNIT: dict[str, str] = {
    "time": "s",
    "force": "N",
    "torque": "Nm",
    "length": "m",
    "slip": "-",
    "angular_velocity": "rad/s",
    "speed": "m/s",
    "count": "",
    "angle": "deg",
}

#: largest plausible magnitude per quantity (SI). No single-wheel test comes within orders of
#: magnitude of these (a 100 t wheel load, 10 m of sinkage); they catch unit mistakes and values
#: whose squares overflow (1e308) before any statistics are computed. Time allows Unix epoch
#: stamps in seconds (1.7e9 s); slip allows a drive-convention slip of a nearly locked wheel
#: (1 - v/(omega r) = -1000 at omega r = v/1000).
PLAUSIBLE_MAX: dict[str, float] = {
    "time": 1e11,
    "force": 1e6,
    "torque": 1e5,
    "length": 10.0,
    "slip": 1e3,
    "angular_velocity": 1e3,
    "speed": 1e2,
    "count": 1e4,
    "angle": 360.0,
}


def plausible_message(quantity: str, value: float) -> str | None:
    """Why ``value`` (SI) is not a plausible ``quantity``, or None when it is."""
    bound = PLAUSIBLE_MAX[quantity]
    if not math.isfinite(value):
        return f"non-finite value {quoted(value)}"
    if abs(value) > bound:
        unit = SI_UNIT[quantity]
        unit = "" if unit in ("", "-") else f" {unit}"
        return (
            f"{value:g}{unit} is outside the plausible range of a {quantity.replace('_', ' ')} "
            f"(|value| <= {bound:g}{unit}; check the unit)"
        )
    return None


_NUMBER_WITH_UNIT = re.compile(
    r"^\s*(?P<num>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(?P<unit>\S.*?)?\s*$"
)


def _normalise(unit: str) -> str:
    u = unit.strip().replace("\u00b7", "*").replace("\u22c5", "*").replace("\u00d7", "*")
    u = re.sub(r"\s*\*\s*", "*", u)
    return re.sub(r"\s+", "*", u).lower()


def accepted_units(quantity: str) -> str:
    """Comma-separated accepted unit spellings for ``quantity`` (for error messages)."""
    return ", ".join(repr(u) if u in ("", "-", "1") else u for u in UNITS[quantity])


def unit_factor(quantity: str, unit: str, where: str) -> float:
    """Factor converting a value in ``unit`` to SI for ``quantity``.

    ``where`` names the column or metadata key for the error message.
    """
    table = UNITS[quantity]
    lookup = {_normalise(k): v for k, v in table.items()}
    key = _normalise(unit)
    if key not in lookup:
        raise LogFormatError(
            f"{where}: unknown {quantity.replace('_', ' ')} unit {quoted(unit)} "
            f"(accepted: {accepted_units(quantity)})"
        )
    return lookup[key]


def parse_value(text: str, quantity: str, where: str, default_unit: str | None = None) -> float:
    """Parse ``"125 mm"``, ``"20 %"`` or ``"315"`` into an SI float.

    A bare number is taken in ``default_unit`` (SI if None).
    """
    m = _NUMBER_WITH_UNIT.match(text)
    if m is None:
        raise LogFormatError(f"{where}: {quoted(text)} is not a number with an optional unit")
    unit = m.group("unit")
    if unit is None:
        unit = default_unit if default_unit is not None else SI_UNIT[quantity]
    value = float(m.group("num")) * unit_factor(quantity, unit, where)
    if not math.isfinite(value):
        raise LogFormatError(f"{where}: value {quoted(text)} is not finite")
    problem = plausible_message(quantity, value)
    if problem is not None:
        raise LogFormatError(f"{where}: {problem}")
    return value
