"""Dependencies of the routes: settings, store, dispatcher and the API token checks.

Write endpoints always need ``Authorization: Bearer <token>``; read endpoints need it too when
``settings.read_requires_token``. Health endpoints never do. Tokens are checked against the
hashes in ``SCM_CALIB_API_TOKENS`` (:meth:`services.config.Settings.token_is_valid`).

An endpoint declares its need with the dependency :func:`require_write` or :func:`require_read`
(:func:`route_needs_token` reads it back); the application checks the token before it reads
the request's body (``services.api.middleware.TokenFirstMiddleware``), so a request without a valid
token is answered 401 whatever its body, and documents the need in its OpenAPI schema.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Depends, HTTPException, Request, status

from services.config import Settings
from services.store import Store

__all__ = [
    "DispatcherDep",
    "SettingsDep",
    "StoreDep",
    "get_dispatcher",
    "get_settings",
    "get_store",
    "require_read",
    "require_write",
    "route_needs_token",
]

_CHALLENGE = {"WWW-Authenticate": "Bearer"}


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_store(request: Request) -> Store:
    store = getattr(request.app.state, "store", None)
    if store is None:  # only outside the lifespan (e.g. a TestClient used without `with`)
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, "the service is starting")
    return store


def get_dispatcher(request: Request) -> Any:
    """Where new work batches go: the local pool, Celery, or None (nothing runs them here)."""
    return getattr(request.app.state, "dispatcher", None)


def get_runtime(request: Request) -> Any:
    return getattr(request.app.state, "runtime", None)


SettingsDep = Annotated[Settings, Depends(get_settings)]
StoreDep = Annotated[Store, Depends(get_store)]
DispatcherDep = Annotated[Any, Depends(get_dispatcher)]


def _unauthorized(message: str) -> HTTPException:
    return HTTPException(status.HTTP_401_UNAUTHORIZED, message, headers=_CHALLENGE)


def check_token(request: Request, settings: Settings) -> None:
    """Raise 401 unless the request carries a valid bearer token."""
    header = request.headers.get("authorization")
    if not header:
        raise _unauthorized("missing API token: send the header 'Authorization: Bearer <token>'")
    scheme, _, token = header.partition(" ")
    token = token.strip()
    if scheme.lower() != "bearer" or not token:
        raise _unauthorized("Authorization header must be 'Bearer <token>'")
    if not settings.api_tokens:
        raise _unauthorized(
            "no API tokens are configured on this server: set SCM_CALIB_API_TOKENS "
            "(`python -m services.config new-token` makes one)"
        )
    if not settings.token_is_valid(token):
        raise _unauthorized("invalid API token")


def token_ok(request: Request, settings: Settings) -> bool:
    """Whether the request carries a valid bearer token (no error either way)."""
    scheme, _, token = (request.headers.get("authorization") or "").partition(" ")
    return scheme.lower() == "bearer" and settings.token_is_valid(token.strip())


def require_write(request: Request, settings: SettingsDep) -> None:
    """Dependency of every endpoint that changes something."""
    check_token(request, settings)


def require_read(request: Request, settings: SettingsDep) -> None:
    """Dependency of the read endpoints (a token only with ``read_requires_token``)."""
    if settings.read_requires_token:
        check_token(request, settings)


def route_needs_token(route: Any, settings: Settings) -> bool:
    """Whether the endpoint of ``route`` (an ``APIRoute``) needs a valid token under
    ``settings``: it depends on :func:`require_write`, or on :func:`require_read` while
    ``settings.read_requires_token``."""
    needs = {getattr(d, "dependency", None) for d in getattr(route, "dependencies", ())}
    return require_write in needs or (require_read in needs and settings.read_requires_token)
