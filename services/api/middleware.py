"""The API's ASGI middleware (body size limit, token before body, JSON depth) and the route
lookups they and the error handlers share."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from fastapi import HTTPException, Request
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute
from starlette.routing import Match

from services.limits import LimitError, check_json_depth

from .deps import check_token, route_needs_token

log = logging.getLogger(__name__)


def error_response(code: int, detail: str, headers: dict[str, str] | None = None) -> JSONResponse:
    """The API's error form: ``{\"detail\": \"<one line>\"}``."""
    return JSONResponse({"detail": detail}, status_code=code, headers=headers)


def api_routes(app: Any) -> list[APIRoute]:
    """The endpoints of the API (their routers' routes; ``app.router.routes`` holds included
    routers rather than their routes in recent FastAPI versions)."""
    return getattr(app.state, "api_routes", [])


def route_of(app: Any, scope: Any) -> APIRoute | None:
    """The endpoint that will answer the request of ``scope`` (path and method), if any."""
    for route in api_routes(app):
        match, _ = route.matches(scope)
        if match is Match.FULL:
            return route
    return None


def allowed_methods(app: Any, scope: Any) -> list[str]:
    """The methods of every endpoint at the path of ``scope`` (Starlette's own 405 names only
    those of the first endpoint it finds at the path)."""
    methods: set[str] = set()
    for route in api_routes(app):
        match, _ = route.matches(scope)
        if match is not Match.NONE:
            methods |= route.methods
    return sorted(methods)


class _BodyTooLarge(HTTPException):
    def __init__(self, detail: str) -> None:
        super().__init__(413, detail)


class BodyLimitMiddleware:
    """Refuse request bodies over a per-path limit with 413, before they are read in full:
    at once from ``Content-Length``, else while the body streams in. ``limit_for(path)``
    gives (limit in bytes, the start of the error message, naming the field)."""

    def __init__(self, app: Any, limit_for: Callable[[str], tuple[int, str]]) -> None:
        self.app = app
        self.limit_for = limit_for

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope.get("method") not in ("POST", "PUT", "PATCH"):
            await self.app(scope, receive, send)
            return
        limit, what = self.limit_for(scope.get("path", ""))
        length = None
        for key, value in scope.get("headers", ()):
            if key == b"content-length":
                try:
                    length = int(value)
                except ValueError:
                    length = None
        if length is not None and length > limit:
            response = error_response(
                413, f"{what}; request body: {length} bytes", {"Connection": "close"}
            )
            await response(scope, receive, send)
            return
        seen = 0

        async def limited() -> Any:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    raise _BodyTooLarge(f"{what}; request body: more than {limit} bytes")
            return message

        await self.app(scope, limited, send)


class TokenFirstMiddleware:
    """Answer 401 (with ``WWW-Authenticate: Bearer``) to a request for an endpoint that needs
    a token (:func:`services.api.deps.route_needs_token`) and carries no valid one, before
    anything reads its body: the answer does not depend on the body (malformed JSON, a body
    over the size limit, too deep a document). The endpoint's own dependency checks the token
    again."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        api = scope.get("app") if scope["type"] == "http" else None
        route = route_of(api, scope) if api is not None else None
        if route is not None:
            settings = api.state.settings
            if route_needs_token(route, settings):
                try:
                    check_token(Request(scope), settings)
                except HTTPException as exc:
                    await error_response(exc.status_code, str(exc.detail), exc.headers)(
                        scope, receive, send
                    )
                    return
        await self.app(scope, receive, send)


class JsonDepthMiddleware:
    """Refuse a JSON request body nested deeper than ``max_depth`` with 422 before anything
    parses it (a deep enough document makes ``json.loads`` or pydantic recurse past
    Python's limit). The body is already bounded by :class:`BodyLimitMiddleware`."""

    def __init__(self, app: Any, max_depth: int) -> None:
        self.app = app
        self.max_depth = max_depth

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope.get("method") not in ("POST", "PUT", "PATCH"):
            await self.app(scope, receive, send)
            return
        ctype = b""
        for key, value in scope.get("headers", ()):
            if key == b"content-type":
                ctype = value.split(b";")[0].strip().lower()
        if not (ctype == b"application/json" or ctype.endswith(b"+json")):
            await self.app(scope, receive, send)
            return
        chunks: list[bytes] = []
        while True:
            try:
                message = await receive()
            except HTTPException as exc:  # over the body limit (outside the exception handlers)
                await error_response(exc.status_code, str(exc.detail), {"Connection": "close"})(
                    scope, receive, send
                )
                return
            if message["type"] != "http.request":
                await self.app(scope, receive, send)
                return
            chunks.append(message.get("body", b""))
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        try:
            check_json_depth(body, self.max_depth)
        except LimitError as exc:
            await error_response(422, str(exc))(scope, receive, send)
            return
        sent = False

        async def replay() -> Any:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


# ---------------------------------------------------------------------------- OpenAPI
