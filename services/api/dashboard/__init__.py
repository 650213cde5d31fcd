"""The web dashboard served by the API at ``/`` (see :mod:`.pages`)."""

from .pages import dashboard_router, mount_static

__all__ = ["dashboard_router", "mount_static"]
