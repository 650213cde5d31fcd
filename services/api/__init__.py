"""The REST API of the calibration service (FastAPI).

``create_app(settings)`` builds the application; ``scm-calib serve`` runs it with uvicorn. Layout
after the full-stack-fastapi-template: :mod:`.main` (app factory, lifespan, error handlers),
:mod:`.deps` (store, dispatcher, token checks), :mod:`.schemas` (request and response models),
:mod:`.routes` (one module per resource). See ``docs/api.md``.

``create_app`` loads :mod:`.main` on first use (PEP 562): a dashboard figure process imports
:mod:`.dashboard.study_figures` (a subpackage of this one) without FastAPI and the application's
routes (0.3-0.6 s of its start on a busy core).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .main import create_app

__all__ = ["create_app"]


def __getattr__(name: str) -> Any:
    if name == "create_app":
        return importlib.import_module(f"{__name__}.main").create_app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
