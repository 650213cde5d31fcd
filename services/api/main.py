"""The application factory: ``create_app(settings)``.

The lifespan opens the store (refusing a database at the wrong schema revision) and picks where
work runs:

* embedded mode (no broker configured): a :class:`worker.local.LocalRuntime` runs every study of
  the database in a local process pool (also the work left pending by a previous server), unless
  ``start_local_runtime=False`` (then studies are created but wait for a server that runs them);
* distributed mode: new work batches are sent to Celery (``celery_dispatcher(settings)``); Celery
  workers run them and a separate ``scm-calib reaper`` re-dispatches lost work.

Errors are ``{"detail": "..."}`` with one line that names the field or resource.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from importlib import metadata
from typing import Any

import sqlalchemy.exc
from fastapi import FastAPI, HTTPException, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from services.config import Settings, get_settings
from services.limits import LimitError, check_json_depth
from services.store import NotFoundError, SchemaVersionError, Store

from .params import NOT_FOUND_PARAMS
from .routes import datasets, health, pooled, presets, sensitivity, studies

log = logging.getLogger(__name__)

__all__ = ["API_DESCRIPTION", "create_app", "format_validation_errors"]

#: largest request body of the endpoints other than uploads
JSON_BODY_LIMIT = 4 * 1024 * 1024
#: room for the multipart framing and the metadata field of an upload
UPLOAD_SLACK = 64 * 1024

API_DESCRIPTION = """\
Bayesian (TMCMC) calibration of Soil Contact Model parameters from single-wheel tests.

Upload SWT logs (`POST /datasets`), submit a study (`POST /studies`, a preset of the paper or a
case document), follow its progress (`GET /studies/{id}`), then read the posterior
(`.../summary`, `.../stages/{j}/samples`). Screen the soil parameters first with a Morris
sensitivity study (`POST /sensitivity`). Write endpoints need `Authorization: Bearer <token>`.
Errors are `{"detail": "..."}`.
"""


def _version() -> str:
    try:
        return metadata.version("scm-calib")
    except metadata.PackageNotFoundError:  # pragma: no cover - source tree without install
        return "0+unknown"


# ---------------------------------------------------------------------------- error handling


def _short(value: Any, width: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def format_validation_errors(errors: list[dict[str, Any]], limit: int = 3) -> str:
    """One line from pydantic/FastAPI validation errors, each naming its location.

    Body fields are named as in the body (``dataset_ids.0``), other parameters with their
    place (``query.limit``, ``path.study_id``)."""
    parts = []
    for err in errors[:limit]:
        loc = [str(p) for p in err.get("loc", ())]
        kind = err.get("type", "")
        if kind == "json_invalid":
            pos = f" at character {loc[1]}" if len(loc) > 1 else ""
            reason = (err.get("ctx") or {}).get("error") or err.get("msg", "")
            parts.append(f"body: invalid JSON{pos}: {reason}")
            continue
        if loc and loc[0] == "body" and len(loc) > 1:
            loc = loc[1:]
        where = ".".join(loc) or "request"
        if kind == "missing":
            msg = "field required"
        elif kind == "extra_forbidden":
            msg = "unknown field"
        else:
            msg = str(err.get("msg", "invalid value")).removeprefix("Value error, ")
            if "input" in err and not isinstance(err["input"], dict | list | bytes):
                msg += f" (got {_short(err['input'])})"
        parts.append(f"{where}: {msg}")
    if len(errors) > limit:
        parts.append(f"and {len(errors) - limit} more")
    return "; ".join(parts)


def _id_out_of_range(errors: list[dict[str, Any]]) -> str | None:
    """ "study 9223372036854775808 not found" when the only problem is a path id outside what
    the database holds (such an id names nothing: 404, as any unknown id)."""
    if not errors:
        return None
    for err in errors:
        loc = err.get("loc", ())
        if not (
            len(loc) == 2
            and loc[0] == "path"
            and loc[1] in NOT_FOUND_PARAMS
            and err.get("type") in ("less_than_equal", "greater_than_equal")
        ):
            return None
    loc, value = errors[0]["loc"], errors[0].get("input")
    return f"{NOT_FOUND_PARAMS[loc[1]]} {value} not found"


def _error(code: int, detail: str, headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=code, headers=headers)


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(HTTPException)
    async def _http(request: Request, exc: HTTPException) -> JSONResponse:
        detail = exc.detail if isinstance(exc.detail, str) else str(jsonable_encoder(exc.detail))
        return _error(exc.status_code, detail, getattr(exc, "headers", None))

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = list(exc.errors())
        missing = _id_out_of_range(errors)
        if missing is not None:
            return _error(404, missing)
        return _error(422, format_validation_errors(errors))

    @app.exception_handler(NotFoundError)
    async def _not_found(request: Request, exc: NotFoundError) -> JSONResponse:
        return _error(404, str(exc))

    @app.exception_handler(SchemaVersionError)
    async def _schema(request: Request, exc: SchemaVersionError) -> JSONResponse:
        return _error(503, str(exc))

    async def _database(request: Request, exc: Exception) -> JSONResponse:
        log.exception("database error on %s %s", request.method, request.url.path)
        orig = getattr(exc, "orig", None) or exc
        lines = str(orig).strip().splitlines()
        reason = f"{type(orig).__name__}: {lines[0]}" if lines else type(orig).__name__
        return _error(
            503,
            f"database unavailable or not at the code's schema revision ({reason}); "
            "see GET /health/ready",
        )

    for cls in (
        sqlalchemy.exc.OperationalError,  # unreachable, locked, SQLite table missing
        sqlalchemy.exc.ProgrammingError,  # PostgreSQL table missing (schema downgraded)
        sqlalchemy.exc.InterfaceError,
    ):
        app.add_exception_handler(cls, _database)

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception) -> JSONResponse:
        log.exception("unhandled error on %s %s", request.method, request.url.path)
        return _error(500, f"internal error ({type(exc).__name__}); see the server log")


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
            response = _error(413, f"{what}; request body: {length} bytes", {"Connection": "close"})
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
                await _error(exc.status_code, str(exc.detail), {"Connection": "close"})(
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
            await _error(422, str(exc))(scope, receive, send)
            return
        sent = False

        async def replay() -> Any:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


# ---------------------------------------------------------------------------- factory


def create_app(
    settings: Settings | None = None,
    *,
    store: Store | None = None,
    start_local_runtime: bool | None = None,
) -> FastAPI:
    """The API application.

    settings: default :func:`services.config.get_settings`. store: an open store on
    ``settings.database_url`` (default: opened in the lifespan and closed at shutdown).
    start_local_runtime: embedded mode only; None or True runs studies in a local process pool,
    False only records them (tests, or an API in front of another embedded server).
    """
    settings = settings or get_settings()
    mode = "embedded" if settings.embedded else "distributed"

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        own = store is None
        st = Store.from_settings(settings) if own else store
        runtime = None
        try:
            if settings.embedded:
                if start_local_runtime is not False:
                    from worker.local import LocalRuntime

                    runtime = LocalRuntime(settings, st).start()
                    app.state.dispatcher = runtime
                else:
                    app.state.dispatcher = None
            else:
                from worker.runtime import celery_dispatcher

                app.state.dispatcher = celery_dispatcher(settings)
            app.state.runtime = runtime
            app.state.store = st
            log.info("scm-calib API (%s mode) on %s", mode, st.engine.url)
            yield
        finally:
            app.state.store = None
            if runtime is not None:
                runtime.stop()
            if own:
                st.close()

    app = FastAPI(
        title="scm-calib",
        version=_version(),
        description=API_DESCRIPTION,
        lifespan=lifespan,
    )
    app.state.settings = settings
    app.state.mode = mode
    app.state.store = None
    app.state.dispatcher = None
    app.state.runtime = None

    def limit_for(path: str) -> tuple[int, str]:
        if path.rstrip("/") == "/datasets":
            return settings.upload_max_bytes + UPLOAD_SLACK, (
                f"file: upload over the limit of {settings.upload_max_bytes} bytes "
                "(server setting SCM_CALIB_UPLOAD_MAX_BYTES)"
            )
        return JSON_BODY_LIMIT, f"body: over the limit of {JSON_BODY_LIMIT} bytes"

    app.add_middleware(JsonDepthMiddleware, max_depth=settings.max_json_depth)
    app.add_middleware(BodyLimitMiddleware, limit_for=limit_for)  # outermost: runs first
    _install_error_handlers(app)
    for module in (health, datasets, presets, studies, sensitivity, pooled):
        app.include_router(module.router)
    return app
