"""The web dashboard served by the API at ``/`` (see :mod:`.pages`).

Its names load on first use (PEP 562): a figure process imports :mod:`.study_figures` without the
pages (FastAPI, the templates).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .drawing import FigureProcess
    from .pages import dashboard_router, mount_static
    from .study_figures import FigureCache
    from .warmer import FigureWarmer

__all__ = ["FigureCache", "FigureProcess", "FigureWarmer", "dashboard_router", "mount_static"]

_WHERE = {
    "FigureCache": "study_figures",
    "FigureProcess": "drawing",
    "FigureWarmer": "warmer",
    "dashboard_router": "pages",
    "mount_static": "pages",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
