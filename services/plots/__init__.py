"""Figures (matplotlib, Agg backend): SWT signals, posteriors, sensitivity.

Submodules load on first use (PEP 562): ``import services.plots as plots`` then
``plots.fit.fit_figure(...)`` imports matplotlib (about a second) only when a figure is drawn,
so the API, its workers and the CLI's non-drawing commands start without it.
:mod:`services.plots.choices` (which pairs, which widths to show) needs no matplotlib.
"""

from __future__ import annotations

import importlib
from types import ModuleType

_SUBMODULES = frozenset(
    {"choices", "figures", "fit", "posterior", "predict", "ranks", "sensitivity", "stages", "swt"}
)


def __getattr__(name: str) -> ModuleType:
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(_SUBMODULES)
