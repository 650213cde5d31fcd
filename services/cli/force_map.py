"""``scm-calib predict --sweep`` and ``--map``: their ranges, and the force map's CSV file.

A range is ``KEY=LO:HI:N`` (N values from LO to HI): the symmetric slip (``slip``, or a lab's
other names of a slip: ``slip_ratio``, ``slip_symmetric``, ``slip_lab``) or the slip angle in
degrees (``slip_angle``, or a lab's ``beta``, ``steering_angle``, ``yaw_angle``,
``slip_angle_deg``; keys as the metadata parser reads them, docs/data-formats.md).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from scm_core.calibration.predict import ConditionPrediction
from scm_core.signals.metadata import CONDITION_KEYS, normalise_key
from scm_core.signals.responses import RESPONSES
from services.studies.kinds.prediction import MAX_CONDITIONS

from .common import CLIError

#: key of a range -> the condition fields whose metadata names (aliases) it takes
_SWEPT = {"slip": ("slip", "slip_symmetric"), "slip_angle": ("slip_angle",)}
_KEY_OF = {
    alias: key for key, fields in _SWEPT.items() for f in fields for alias in CONDITION_KEYS[f][1]
}
#: key -> (least LO, most HI, HI may equal it, what the message says)
_LIMITS = {
    "slip": (-1.0, 1.0, False, "-1 <= LO < HI < 1"),
    "slip_angle": (-90.0, 90.0, True, "-90 <= LO < HI <= 90 (deg)"),
}
#: the most points of a sweep, and of a force map: one prediction study's conditions
MAX_POINTS = MAX_CONDITIONS
#: ``--map`` given bare: symmetric slips -0.9..0.9 by 0.1, slip angles 0..90 deg by 15
DEFAULT_MAP = {"slip": (-0.9, 0.9, 19), "slip_angle": (0.0, 90.0, 7)}
#: responses' columns in the CSV (SI, as predictions.json)
_COLUMNS = tuple((r.key, r.unit) for r in RESPONSES)


def parse_range(option: str, spec: str, whole: str | None = None) -> tuple[str, list[float]]:
    """``slip=LO:HI:N`` or ``slip_angle=LO:HI:N`` (or a lab's alias of either) -> (the key,
    N values from LO to HI: symmetric slips, -1 = locked; slip angles [deg]). CLIError naming
    ``option`` and the ``whole`` spec (default ``spec``) when malformed or out of range."""
    shown = f"{option} {whole or repr(spec)}"
    raw, sep, rng = spec.partition("=")
    key = _KEY_OF.get(normalise_key(raw))
    parts = rng.split(":")
    if key is None or not sep or len(parts) != 3:
        raise CLIError(
            f"{shown}: expected slip=LO:HI:N or slip_angle=LO:HI:N, e.g. slip=-1:0.9:24 or "
            "slip_angle=0:90:7"
        )
    try:
        lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise CLIError(f"{shown}: LO and HI must be numbers, N a whole number") from None
    least, most, closed, words = _LIMITS[key]
    if not (least <= lo < hi and (hi <= most if closed else hi < most)) or not 2 <= n <= MAX_POINTS:
        raise CLIError(f"{shown}: {key} needs {words} and 2 <= N <= {MAX_POINTS}")
    return key, [float(x) for x in np.linspace(lo, hi, n)]


def parse_map(spec: str | None) -> tuple[list[float], list[float]] | None:
    """``--map`` -> (symmetric slips, slip angles [deg]) of the force map's grid, None when not
    asked. ``spec``: "" (``--map`` bare: :data:`DEFAULT_MAP`) or ``slip=LO:HI:N``,
    ``slip_angle=LO:HI:N`` or both comma-separated (the one left out: its default); at most
    :data:`MAX_POINTS` points in all."""
    if spec is None:
        return None
    axes = {k: [float(x) for x in np.linspace(*v)] for k, v in DEFAULT_MAP.items()}
    given: set[str] = set()
    for part in (p.strip() for p in spec.split(",")):
        if not part:
            continue
        key, values = parse_range("--map", part, repr(spec))
        if key in given:
            raise CLIError(f"--map {spec!r}: {key} is given twice")
        given.add(key)
        axes[key] = values
    slips, angles = axes["slip"], axes["slip_angle"]
    if len(slips) * len(angles) > MAX_POINTS:
        raise CLIError(
            f"--map {spec!r}: {len(slips)} slips x {len(angles)} slip angles = "
            f"{len(slips) * len(angles)} points, over the limit of {MAX_POINTS}"
        )
    return slips, angles


#: conditions every point of a map shares, with their units, as the CSV's header states them
_HELD = (
    ("W", "N"),
    ("carriage_speed", "m/s"),
    ("R", "m"),
    ("b", "m"),
    ("n_grousers", ""),
    ("grouser_height", "m"),
)


def held_conditions(conditions: Mapping[str, Any]) -> dict[str, str]:
    """The conditions a force map holds at every point (of its template's ``conditions``,
    simulator keys in SI), as its CSV header states them: "W" -> "315 N"."""
    return {k: f"{conditions[k]:.7g}{' ' + u if u else ''}" for k, u in _HELD if k in conditions}


def _number(x: float | None) -> str:
    return "nan" if x is None or not math.isfinite(x) else f"{x:.7g}"


def write_force_map(
    path: Path, points: Sequence[ConditionPrediction], about: Mapping[str, Any]
) -> Path:
    """The force map ``points`` (a :func:`~scm_core.calibration.predict.map_targets` grid's
    predictions) as CSV: ``# key: value`` lines (``about``: the study, draws, seed and the
    conditions every point shares, :func:`held_conditions`), then one row per point: the
    symmetric slip, the slip angle [deg] and per response the median and central 95 % band
    (lo, hi) of the simulated steady means in SI (F, Fy [N], T [N m], z [m], as
    predictions.json), and the number of draws whose run failed there."""
    keys = [k for k, _ in _COLUMNS if points and k in points[0].responses]
    lines = [
        "# scm-calib force map: posterior median and central 95 % band (lo, hi) of the "
        "simulated steady means (parameter uncertainty, without the prediction-error noise)",
        "# units: SI as in predictions.json (F, Fy in N; T in N m; z in m); slip symmetric "
        "(omega r - v) / max(v, omega r) with v the carriage speed, -1 = locked",
        "# slip_angle: deg between the wheel's heading and the carriage's travel; Fy > 0 "
        "pushes the wheel back against its slide toward -y (slip_angle > 0)",
        *(f"# {k}: {v}" for k, v in about.items()),
    ]
    header = ["slip", "slip_angle [deg]"]
    header += [f"{k}_{q} [{u}]" for k, u in _COLUMNS if k in keys for q in ("median", "lo", "hi")]
    header.append("n_failed")
    with path.open("w", newline="", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(header)
        for p in points:
            row = [_number(p.slip_symmetric), _number(p.conditions.get("slip_angle", 0.0))]
            for k in keys:
                b = p.responses[k].simulated
                row += [_number(b.median), _number(b.lo), _number(b.hi)]
            writer.writerow([*row, p.n_failed])
    return path
