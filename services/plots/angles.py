"""A steered study's figures: a column of panels per slip angle (issue 70).

The slip angle (deg, between the wheel's heading and the carriage's travel) is a test
condition; a figure against slip that mixed the angles on one axis would draw a locked wheel at
0 deg beside one at 90 deg. These helpers group what a figure draws by angle and lay the panels
out as a grid, a row per response and a column per angle, each row on one y range (a
response's growth with the angle shows). No matplotlib: the grid is a
:class:`~services.plots.chart.Chart`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any, TypeVar

from .chart import Chart, Panel

__all__ = ["angle_grid", "angle_of", "angle_title", "by_slip_angle", "share_y", "steered"]

T = TypeVar("T")
R = TypeVar("R")

#: layer kinds whose y values a shared range covers, and the fields that hold them
_Y_KINDS = frozenset({"line", "band", "errorbars", "points"})
_Y_FIELDS = ("y", "lo", "hi")


def angle_of(conditions: Mapping[str, Any] | Any) -> float:
    """The slip angle [deg] of a conditions mapping (a prediction's) or object (a dataset's
    :class:`~scm_core.signals.TestConditions`); 0 (driven straight) where none is given."""
    if isinstance(conditions, Mapping):
        value = conditions.get("slip_angle")
    else:
        value = getattr(conditions, "slip_angle", None)
    return float(value or 0.0)


def by_slip_angle(items: Iterable[T], angle: Callable[[T], float]) -> list[tuple[float, list[T]]]:
    """``items`` grouped by ``angle(item)`` [deg], the angles ascending, each group in the
    order given."""
    groups: dict[float, list[T]] = {}
    for item in items:
        groups.setdefault(float(angle(item)), []).append(item)
    return sorted(groups.items())


def steered(items: Iterable[T], angle: Callable[[T], float]) -> bool:
    """Whether any of ``items`` is at a slip angle other than 0 (its figure then gets a
    column per angle)."""
    return any(angle(item) for item in items)


def angle_title(angle: float) -> str:
    """A column's title: "slip angle 30 deg"."""
    return f"slip angle {angle:g} deg"


def share_y(panels: Sequence[Panel]) -> None:
    """Put ``panels`` on one y range: that of their lines', bands', bars' and points' y values,
    with a twentieth of the span as margin (left as they are if they hold none)."""
    values = [
        v
        for p in panels
        for layer in p.layers
        if layer["kind"] in _Y_KINDS
        for f in _Y_FIELDS
        for v in layer.get(f) or ()
        if v is not None
    ]
    if not values:
        return
    lo, hi = min(values), max(values)
    pad = (hi - lo) / 20.0 or max(abs(hi), 1.0) * 0.05
    for p in panels:
        p.y = replace(p.y, lo=lo - pad, hi=hi + pad)


def angle_grid(
    title: str,
    rows: Sequence[R],
    angles: Sequence[float],
    panel: Callable[[R, float, bool], Panel],
    width: float = 4.2,
    height: float = 2.6,
) -> Chart:
    """A chart of a row per ``rows`` entry (a response) and a column per angle of ``angles``
    [deg]: ``panel(row, angle, bottom)`` makes each (``bottom``: the last row, which labels
    the x axis); the top row's panels are titled with their angle, each row shares its y
    range and one legend is drawn, in the top row's panel that names the most layers (a sweep
    at one angle, a wheel tested at some). ``width``, ``height``: a panel's size [in]. On a
    narrow screen an angle's panels stay together."""
    grid = []
    for k, row in enumerate(rows):
        cells = [panel(row, a, k == len(rows) - 1) for a in angles]
        share_y(cells)
        grid.append(cells)
    if grid:
        top = grid[0]
        for p, a in zip(top, angles, strict=True):
            p.title = angle_title(a)
        named = [len({la.get("label") for la in p.layers} - {None, ""}) for p in top]
        for p in (p for cells in grid for p in cells):
            p.legend = None
        top[named.index(max(named))].legend = "best"
    return Chart(
        title,
        [p for cells in grid for p in cells],
        columns=len(angles),
        size=(max(width * len(angles), 7.0), height * len(rows) + 0.8),
        reflow="columns",
    )
