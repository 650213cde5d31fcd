"""Draw a :class:`~services.plots.chart.Chart` with matplotlib (files, SVG and PNG downloads).

The browser draws the same chart from its JSON (``charts.js``); this is its twin for a file, so
that what a figure shows is said once, in the chart's builder.
"""

from __future__ import annotations

import math
import textwrap
from typing import Any

import numpy as np
from matplotlib import rcParams
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties

from .chart import Axis, Chart, Panel

__all__ = ["draw"]

_DASH = {None: "-", "dashed": "--", "dotted": ":"}


def _arr(values: list[float | None]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def draw(chart: Chart) -> Figure:
    """``chart`` as a matplotlib figure (constrained layout; empty cells hidden)."""
    fig = Figure(figsize=chart.size, layout="constrained")
    axes = np.atleast_1d(fig.subplots(chart.rows, chart.columns, squeeze=False)).ravel()
    for ax, panel in zip(axes, chart.panels, strict=False):
        if panel is None:
            ax.set_visible(False)
        else:
            _panel(ax, panel)
    for ax in axes[len(chart.panels) :]:
        ax.set_visible(False)
    fig.suptitle(_fitted_title(chart.title, chart.size[0]))
    return fig


def _fitted_title(title: str, width: float) -> str:
    """``title`` broken at spaces into lines that fit a figure ``width`` [in] wide at the
    figure title's font size (a glyph taken as 0.6 em: DejaVu Sans averages about 0.55)."""
    size = FontProperties(size=rcParams["figure.titlesize"]).get_size_in_points()
    chars = max(16, int(0.95 * width * 72.0 / (0.6 * size)))
    return "\n".join(textwrap.wrap(title, chars, break_long_words=False))


def _panel(ax: Any, panel: Panel) -> None:
    for layer in panel.layers:
        _LAYERS[layer["kind"]](ax, layer)
    _axis(ax, panel.x, "x")
    _axis(ax, panel.y, "y")
    if panel.title:
        ax.set_title(panel.title, fontsize=9)
    ax.grid(alpha=0.3, which="both" if "log" in (panel.x.scale, panel.y.scale) else "major")
    if panel.top is not None:
        label, a, b = panel.top
        top = ax.secondary_xaxis("top", functions=(lambda t: (t - a) / b, lambda s: a + b * s))
        top.set_xlabel(label, fontsize=7)
        top.tick_params(labelsize=7)
    if panel.legend and any(layer.get("label") for layer in panel.layers):
        ax.legend(fontsize=7, loc=panel.legend)


def _axis(ax: Any, axis: Axis, which: str) -> None:
    getattr(ax, f"set_{which}label")(axis.label)
    if axis.scale == "log":
        getattr(ax, f"set_{which}scale")("log")
    elif not axis.integer:
        ax.ticklabel_format(axis=which, style="sci", scilimits=(-3, 4))
    if axis.lo is not None or axis.hi is not None:
        getattr(ax, f"set_{which}lim")(axis.lo, axis.hi)
    target = ax.xaxis if which == "x" else ax.yaxis
    if axis.integer:
        target.get_major_locator().set_params(integer=True)
    if not axis.tick_labels:
        getattr(ax, f"set_{which}ticklabels")([])
        if which == "y":
            ax.set_yticks([])
    ax.tick_params(labelsize=8)


def _line(ax: Any, d: dict[str, Any]) -> None:
    ax.plot(
        _arr(d["x"]),
        _arr(d["y"]),
        ls=_DASH[d["dash"]],
        marker=d["marker"],
        ms=3.5 if d["marker"] else None,
        color=d["color"],
        lw=d["width"],
        alpha=d["opacity"],
        label=d["label"],
    )


def _band(ax: Any, d: dict[str, Any]) -> None:
    ax.fill_between(
        _arr(d["x"]),
        _arr(d["lo"]),
        _arr(d["hi"]),
        color=d["color"],
        alpha=d["opacity"],
        lw=0,
        label=d["label"],
    )


def _bars(ax: Any, d: dict[str, Any]) -> None:
    ax.stairs(
        _arr(d["heights"]),
        _arr(d["edges"]),
        fill=d["fill"],
        color=d["color"],
        alpha=d["opacity"],
        lw=1.4 if not d["fill"] else 0,
        label=d["label"],
    )


def _points(ax: Any, d: dict[str, Any]) -> None:
    ax.scatter(
        _arr(d["x"]),
        _arr(d["y"]),
        s=(2.0 * d["size"]) ** 2 * 0.6,
        color=d["color"],
        alpha=d["opacity"],
        marker=d.get("symbol", "o"),
        lw=0,
        label=d["label"],
        rasterized=True,
    )


def _errorbars(ax: Any, d: dict[str, Any]) -> None:
    y = _arr(d["y"])
    ax.errorbar(
        _arr(d["x"]),
        y,
        yerr=[y - _arr(d["lo"]), _arr(d["hi"]) - y],
        fmt="_",
        color=d["color"],
        ms=9,
        elinewidth=d["width"],
        capsize=3,
        label=d["label"],
    )


def _contours(ax: Any, d: dict[str, Any]) -> None:
    label = d["label"]
    for level in d["levels"]:
        for path in level["paths"]:
            ax.plot(
                _arr(path["x"]), _arr(path["y"]), color=level["color"], lw=d["width"], label=label
            )
            label = None


def _vline(ax: Any, d: dict[str, Any]) -> None:
    ax.axvline(d["x"], color=d["color"], lw=d["width"], ls=_DASH[d["dash"]], label=d["label"])


def _hline(ax: Any, d: dict[str, Any]) -> None:
    ax.axhline(d["y"], color=d["color"], lw=d["width"], ls=_DASH[d["dash"]], label=d["label"])


def _segment(ax: Any, d: dict[str, Any]) -> None:
    ax.hlines(d["y"], d["x0"], d["x1"], colors=d["color"], lw=d["width"], label=d["label"])


def _vspan(ax: Any, d: dict[str, Any]) -> None:
    ax.axvspan(d["x0"], d["x1"], color=d["color"], alpha=d["opacity"], lw=0, label=d["label"])


def _hspan(ax: Any, d: dict[str, Any]) -> None:
    ax.axhspan(d["y0"], d["y1"], color=d["color"], alpha=d["opacity"], lw=0, label=d["label"])


def _marker(ax: Any, d: dict[str, Any]) -> None:
    if d["x"] is None or d["y"] is None or not all(math.isfinite(v) for v in (d["x"], d["y"])):
        return
    ax.plot(d["x"], d["y"], d["symbol"], color=d["color"], ms=d["size"], mew=2, label=d["label"])


def _text(ax: Any, d: dict[str, Any]) -> None:
    ax.text(d["fx"], d["fy"], d["text"], transform=ax.transAxes, va="top", fontsize=8)


_LAYERS = {
    "line": _line,
    "band": _band,
    "bars": _bars,
    "points": _points,
    "errorbars": _errorbars,
    "contours": _contours,
    "vline": _vline,
    "hline": _hline,
    "segment": _segment,
    "vspan": _vspan,
    "hspan": _hspan,
    "marker": _marker,
    "text": _text,
}
