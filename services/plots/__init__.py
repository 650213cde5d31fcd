"""Figures: SWT signals, posteriors, sensitivity.

The figures of a study's stages are built as :class:`~services.plots.chart.Chart` data (no
matplotlib), drawn by :func:`services.plots.mpl.draw` for files and downloads and by the
dashboard's script in the browser; the others are matplotlib figures (Agg backend).
Submodules load on first use (PEP 562): ``import services.plots as plots`` then
``plots.mpl.draw(...)`` imports matplotlib (about a second) only when a figure is drawn,
so the API, its workers and the CLI's non-drawing commands start without it.
:mod:`services.plots.choices` (which pairs, which widths to show) and the chart builders need
no matplotlib.
"""

from __future__ import annotations

import importlib
from types import ModuleType

_SUBMODULES = frozenset(
    {
        "angles",
        "chart",
        "choices",
        "figures",
        "fit",
        "mpl",
        "posterior",
        "predict",
        "ranks",
        "sensitivity",
        "stages",
        "swt",
    }
)


def __getattr__(name: str) -> ModuleType:
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(_SUBMODULES)
