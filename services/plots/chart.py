"""A figure as data: a grid of panels, each two axes and a list of layers.

One description of what a figure shows, drawn two ways: by matplotlib for files and downloads
(:func:`services.plots.mpl.draw`) and by the dashboard's script in the browser
(``services/api/dashboard/static/charts.js``) from :meth:`Chart.to_json`. A stage's figures then
cost the server the numbers (quantiles, kernel densities, contour paths: milliseconds) instead
of matplotlib's layout of text and ticks (a second or more per stage, issue 45).

Layers are plain dicts with a ``kind``; their coordinates are data coordinates (on a log axis
the values themselves, not their logarithms). In the JSON, arrays are lists of numbers with
``null`` for a missing value (NaN: a gap in a line), rounded to :data:`DIGITS` significant
digits.

==========  ==================================================================================
kind        fields
==========  ==================================================================================
line        x, y, color, width, dash ("dashed", "dotted" or null), marker ("o", "s", "^" or
            null), opacity, label
band        x, lo, hi, color, opacity, label: the area between two curves
bars        edges (n + 1), heights (n), color, opacity, fill (false: an outline), label
points      x, y, color, size (marker radius [px]), opacity, symbol ("o" circle, "s" square),
            label
errorbars   x, y, lo, hi, color, width, label: at each x a bar from lo to hi with caps and a
            tick at y (a median and its interval)
contours    levels: [{value, color, paths: [{x, y}, ...]}, ...], width, label
vline       x, color, width, dash, label; hline: y, ...
segment     x0, x1, y, color, width, label: a horizontal segment (a mean over a window)
vspan       x0, x1, color, opacity, label; hspan: y0, y1, ...: a shaded strip
marker      x, y, symbol ("+"), color, size, label
text        text, fx, fy: a note at fractions of the panel (0, 0 bottom left)
==========  ==================================================================================
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "COLORS",
    "DIGITS",
    "VIRIDIS",
    "Axis",
    "Chart",
    "Panel",
    "band",
    "bars",
    "contours",
    "errorbars",
    "hline",
    "hspan",
    "line",
    "marker",
    "numbers",
    "points",
    "segment",
    "text",
    "vline",
    "vspan",
]

#: matplotlib's "tab" colours and greys the figures use, as the browser needs them
COLORS = {
    "blue": "#1f77b4",
    "orange": "#ff7f0e",
    "green": "#2ca02c",
    "red": "#d62728",
    "purple": "#9467bd",
    "brown": "#8c564b",
    "black": "#000000",
    "grey": "#808080",
    "dark": "#4d4d4d",
    "mid": "#595959",
    "light": "#bfbfbf",
    "pale": "#cccccc",
}

#: viridis at eight evenly spaced points (contour levels low to high, matplotlib's colormap)
VIRIDIS = (
    "#440154",
    "#46327e",
    "#365c8d",
    "#277f8e",
    "#1fa187",
    "#4ac16d",
    "#a0da39",
    "#fde725",
)


def viridis(k: int, n: int) -> str:
    """The colour of level ``k`` of ``n`` (0 lowest) from :data:`VIRIDIS`."""
    return VIRIDIS[round(k * (len(VIRIDIS) - 1) / max(n - 1, 1))]


#: significant digits of a chart's numbers: 1e-5 of a value, far below a pixel, and above the
#: four the hover readout shows; a fit of two 180 s logs is 37 KB gzipped (64 KB with six)
DIGITS = 5


def numbers(values: Iterable[float] | np.ndarray) -> list[float | None]:
    """A JSON list of ``values`` to :data:`DIGITS` significant digits, None for NaN or
    infinity."""
    return [_number(v) for v in np.asarray(values, dtype=float).ravel()]


def _number(v: float | None) -> float | None:
    if v is None or not math.isfinite(float(v)):
        return None
    return float(f"{float(v):.{DIGITS}g}")


@dataclass(frozen=True)
class Axis:
    """One axis of a panel: its label, scale ("linear" or "log"), limits (None: fitted to the
    layers), integer ticks (stage indices) and whether its tick labels show."""

    label: str = ""
    scale: str = "linear"
    lo: float | None = None
    hi: float | None = None
    integer: bool = False
    tick_labels: bool = True

    def to_json(self) -> dict[str, Any]:
        return {
            "label": self.label,
            "scale": self.scale,
            "lo": _number(self.lo),
            "hi": _number(self.hi),
            "integer": self.integer,
            "tick_labels": self.tick_labels,
        }


@dataclass
class Panel:
    """A pair of axes with its layers, drawn in order. ``legend``: where the legend of the
    labelled layers goes ("best", "upper right", "lower right" ...; None: none). ``top``: a
    second x axis on top, (label, a, b) with top value = (x - a) / b (e.g. another unit of the
    same quantity)."""

    x: Axis
    y: Axis
    layers: list[dict[str, Any]] = field(default_factory=list)
    title: str | None = None
    legend: str | None = "best"
    top: tuple[str, float, float] | None = None

    def add(self, *layers: dict[str, Any]) -> Panel:
        self.layers.extend(layers)
        return self

    def to_json(self) -> dict[str, Any]:
        return {
            "title": self.title,
            "x": self.x.to_json(),
            "y": self.y.to_json(),
            "layers": self.layers,
            "legend": self.legend,
            "top": None
            if self.top is None
            else {"label": self.top[0], "a": _number(self.top[1]), "b": _number(self.top[2])},
        }


@dataclass
class Chart:
    """A figure: ``panels`` in rows of ``columns`` (None leaves a cell empty), a title, and
    the size matplotlib draws it at ([in]; the browser fits it to the page's width, with fewer
    columns on a narrow screen: the panels re-flowed row by row or, with ``reflow``
    "columns", column by column, where a column belongs together: Fig. 3's dataset; "none"
    keeps the grid, a pair matrix's, which then scrolls sideways in its box on a phone)."""

    title: str
    panels: list[Panel | None]
    columns: int = 1
    size: tuple[float, float] = (8.0, 4.0)
    reflow: str = "rows"

    @property
    def rows(self) -> int:
        return max(1, math.ceil(len(self.panels) / max(self.columns, 1)))

    def to_json(self) -> dict[str, Any]:
        return {
            "title": self.title,
            "columns": self.columns,
            "size": list(self.size),
            "reflow": self.reflow,
            "panels": [None if p is None else p.to_json() for p in self.panels],
        }


# --------------------------------------------------------------------------------- layers


def _style(color: str, label: str | None, opacity: float = 1.0, **more: Any) -> dict[str, Any]:
    return {"color": COLORS.get(color, color), "label": label, "opacity": opacity, **more}


def line(
    x: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    color: str = "blue",
    width: float = 1.2,
    dash: str | None = None,
    marker: str | None = None,
    opacity: float = 1.0,
    label: str | None = None,
) -> dict[str, Any]:
    return {
        "kind": "line",
        "x": numbers(x),
        "y": numbers(y),
        **_style(color, label, opacity, width=width, dash=dash, marker=marker),
    }


def band(
    x: Sequence[float] | np.ndarray,
    lo: Sequence[float] | np.ndarray,
    hi: Sequence[float] | np.ndarray,
    color: str = "blue",
    opacity: float = 0.2,
    label: str | None = None,
) -> dict[str, Any]:
    return {
        "kind": "band",
        "x": numbers(x),
        "lo": numbers(lo),
        "hi": numbers(hi),
        **_style(color, label, opacity),
    }


def bars(
    edges: Sequence[float] | np.ndarray,
    heights: Sequence[float] | np.ndarray,
    color: str = "blue",
    opacity: float = 1.0,
    fill: bool = True,
    label: str | None = None,
) -> dict[str, Any]:
    return {
        "kind": "bars",
        "edges": numbers(edges),
        "heights": numbers(heights),
        **_style(color, label, opacity, fill=fill),
    }


def points(
    x: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    color: str = "dark",
    size: float = 1.5,
    opacity: float = 0.45,
    label: str | None = None,
    symbol: str = "o",
) -> dict[str, Any]:
    return {
        "kind": "points",
        "x": numbers(x),
        "y": numbers(y),
        **_style(color, label, opacity, size=size, symbol=symbol),
    }


def errorbars(
    x: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    lo: Sequence[float] | np.ndarray,
    hi: Sequence[float] | np.ndarray,
    color: str = "blue",
    width: float = 1.0,
    label: str | None = None,
) -> dict[str, Any]:
    return {
        "kind": "errorbars",
        "x": numbers(x),
        "y": numbers(y),
        "lo": numbers(lo),
        "hi": numbers(hi),
        **_style(color, label, width=width),
    }


def contours(
    levels: Sequence[tuple[float, Sequence[tuple[np.ndarray, np.ndarray]]]],
    width: float = 1.0,
    label: str | None = None,
) -> dict[str, Any]:
    """Contour lines: ``levels`` (value, [(x, y), ...] paths) from low to high, coloured by
    viridis."""
    n = len(levels)
    return {
        "kind": "contours",
        "levels": [
            {
                "value": _number(value),
                "color": viridis(k, n),
                "paths": [{"x": numbers(px), "y": numbers(py)} for px, py in paths],
            }
            for k, (value, paths) in enumerate(levels)
        ],
        "width": width,
        "label": label,
    }


def vline(
    x: float,
    color: str = "red",
    width: float = 1.2,
    dash: str | None = None,
    label: str | None = None,
) -> dict[str, Any]:
    return {"kind": "vline", "x": _number(x), **_style(color, label, width=width, dash=dash)}


def hline(
    y: float,
    color: str = "grey",
    width: float = 0.8,
    dash: str | None = None,
    label: str | None = None,
) -> dict[str, Any]:
    return {"kind": "hline", "y": _number(y), **_style(color, label, width=width, dash=dash)}


def segment(
    x0: float,
    x1: float,
    y: float,
    color: str = "black",
    width: float = 2.2,
    label: str | None = None,
) -> dict[str, Any]:
    return {
        "kind": "segment",
        "x0": _number(x0),
        "x1": _number(x1),
        "y": _number(y),
        **_style(color, label, width=width),
    }


def vspan(
    x0: float, x1: float, color: str = "grey", opacity: float = 0.08, label: str | None = None
) -> dict[str, Any]:
    return {"kind": "vspan", "x0": _number(x0), "x1": _number(x1), **_style(color, label, opacity)}


def hspan(
    y0: float, y1: float, color: str = "pale", opacity: float = 0.6, label: str | None = None
) -> dict[str, Any]:
    return {"kind": "hspan", "y0": _number(y0), "y1": _number(y1), **_style(color, label, opacity)}


def marker(
    x: float,
    y: float,
    symbol: str = "+",
    color: str = "black",
    size: float = 12.0,
    label: str | None = None,
) -> dict[str, Any]:
    return {
        "kind": "marker",
        "x": _number(x),
        "y": _number(y),
        **_style(color, label, symbol=symbol, size=size),
    }


def text(note: str, fx: float = 0.02, fy: float = 0.95) -> dict[str, Any]:
    return {"kind": "text", "text": note, "fx": fx, "fy": fy}
