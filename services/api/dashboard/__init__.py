"""The web dashboard served by the API at ``/`` (see :mod:`.pages`)."""

from .drawing import FigureProcess
from .figures import FigureCache
from .pages import dashboard_router, mount_static
from .warmer import FigureWarmer

__all__ = ["FigureCache", "FigureProcess", "FigureWarmer", "dashboard_router", "mount_static"]
