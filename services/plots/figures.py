"""Writing figures: to a file (format from its suffix) or to bytes (SVG or PNG) for HTTP."""

from __future__ import annotations

import io
import json
import math
import re
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # a figure comes drawn by matplotlib; FORMATS alone needs none of it
    from matplotlib.figure import Figure

__all__ = ["FORMATS", "axes_geometry", "render", "save"]

#: formats figures are served in, with their media types
FORMATS = {"svg": "image/svg+xml", "png": "image/png"}

#: a coordinate in an SVG path with more than one decimal (matplotlib writes six, in points)
_LONG_DECIMAL = re.compile(rb"(\d\.\d)\d+")
_PATH_DATA = re.compile(rb' d="[^"]*"')


def _round_path_data(svg: bytes) -> bytes:
    """SVG ``svg`` with its path coordinates cut to 0.1 pt (0.15 px at 110 dpi, below what a
    screen shows): the figure looks the same and its long curves (signals, samples) take half
    the bytes compressed (issue 45: Fig. 3 of two logs 78 KB -> 39 KB gzipped)."""
    return _PATH_DATA.sub(lambda m: _LONG_DECIMAL.sub(rb"\1", m.group(0)), svg)


def save(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (PNG, SVG or PDF by the suffix)."""
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path


def render(fig: Figure, fmt: str, dpi: int = 110) -> bytes:
    """``fig`` as the bytes of an SVG or PNG image (the SVG keeps no creation date, so the
    same figure gives the same bytes)."""
    if fmt not in FORMATS:
        raise ValueError(f"figure format must be one of {sorted(FORMATS)}, got {fmt!r}")
    buf = io.BytesIO()
    metadata = {"Date": None} if fmt == "svg" else {}
    # SVG text as text (the page's fonts), not glyph paths; element ids from a fixed salt
    import matplotlib

    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "scm-calib"}):
        fig.savefig(buf, format=fmt, dpi=dpi, metadata=metadata)
    if fmt != "svg":
        return buf.getvalue()
    return _with_axes(_round_path_data(buf.getvalue()), axes_geometry(fig))


def axes_geometry(fig: Figure) -> list[dict[str, object]]:
    """Where each data axes of a drawn ``fig`` lies and what it shows, for a reader of the
    image that maps a point of it to data coordinates (the dashboard's hover readout):
    ``box`` [left, top, right, bottom] as fractions of the image's width and height from its
    top left, ``x`` and ``y`` the axis limits at the box's left/right and bottom/top,
    ``xscale``/``yscale`` "linear" or "log", and the axis labels. Axes without a visible
    frame (legends' own, colour bars without limits) and twins after the first of a box are
    left out."""
    out: list[dict[str, object]] = []
    boxes = set()
    for ax in fig.axes:
        if not (ax.get_visible() and ax.axison):
            continue
        pos = ax.get_position()
        box = tuple(round(v, 5) for v in (pos.x0, 1.0 - pos.y1, pos.x1, 1.0 - pos.y0))
        scales = (ax.get_xscale(), ax.get_yscale())
        if box in boxes or any(sc not in ("linear", "log") for sc in scales):
            continue
        limits = [float(v) for v in (*ax.get_xlim(), *ax.get_ylim())]
        if not all(math.isfinite(v) for v in limits):
            continue
        boxes.add(box)
        out.append(
            {
                "box": list(box),
                "x": [float(f"{v:.6g}") for v in limits[:2]],
                "y": [float(f"{v:.6g}") for v in limits[2:]],
                "xscale": scales[0],
                "yscale": scales[1],
                "xlabel": ax.get_xlabel(),
                "ylabel": ax.get_ylabel(),
            }
        )
    return out


def _with_axes(svg: bytes, axes: list[dict[str, object]]) -> bytes:
    """``svg`` with ``axes`` (:func:`axes_geometry`) as JSON in a ``<metadata id="axes">``
    element right after the root's opening tag (no ``<``/``&`` in it: JSON escapes them)."""
    text = json.dumps(axes, separators=(",", ":"), ensure_ascii=True)
    text = text.replace("&", "\\u0026").replace("<", "\\u003c").replace(">", "\\u003e")
    start = svg.index(b"<svg")
    end = svg.index(b">", start) + 1
    return svg[:end] + b'\n <metadata id="axes">' + text.encode() + b"</metadata>" + svg[end:]
