"""Writing figures: to a file (format from its suffix) or to bytes (SVG or PNG) for HTTP."""

from __future__ import annotations

import io
import re
from pathlib import Path

import matplotlib
from matplotlib.figure import Figure

__all__ = ["FORMATS", "render", "save"]

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
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "scm-calib"}):
        fig.savefig(buf, format=fmt, dpi=dpi, metadata=metadata)
    return _round_path_data(buf.getvalue()) if fmt == "svg" else buf.getvalue()
