"""How the dashboard's templates write numbers, durations and failed runs (Jinja filters and
globals, registered by :func:`register`)."""

from __future__ import annotations

import math
from typing import Any

from jinja2 import Environment

from scm_core.calibration.failures import describe_failures

__all__ = ["duration", "num", "register"]


def num(x: Any, digits: int = 4) -> str:
    """An int with thousands separators, a float to ``digits`` significant digits, "–" for
    None."""
    if x is None:
        return "–"
    if isinstance(x, int):
        return f"{x:,}"
    if not math.isfinite(x):
        return str(x)
    return f"{x:.{digits}g}"


def duration(seconds: float | None) -> str:
    """ "42 s", "3 min 05 s", "1 h 02 min"; "–" for None."""
    if seconds is None:
        return "–"
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


def register(env: Environment) -> None:
    """The filters ``num`` and ``duration`` and the global ``failures(failed, by)`` ("4 failed:
    3 bottomed out, 1 unstable")."""
    env.filters["num"] = num
    env.filters["duration"] = duration
    env.globals["failures"] = describe_failures
