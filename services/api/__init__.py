"""The REST API of the calibration service (FastAPI).

``create_app(settings)`` builds the application; ``scm-calib serve`` runs it with uvicorn. Layout
after the full-stack-fastapi-template: :mod:`.main` (app factory, lifespan, error handlers),
:mod:`.deps` (store, dispatcher, token checks), :mod:`.schemas` (request and response models),
:mod:`.routes` (one module per resource). See ``docs/api.md``.
"""

from .main import create_app

__all__ = ["create_app"]
