"""The web dashboard served by the API at ``/`` (see :mod:`.pages`)."""

from .figures import FigureCache
from .pages import dashboard_router, mount_static
from .warmer import FigureWarmer

__all__ = ["FigureCache", "FigureWarmer", "dashboard_router", "mount_static"]
