"""The application factory: ``create_app(settings)``.

The lifespan opens the store (refusing a database at the wrong schema revision) and picks where
work runs:

* embedded mode (no broker configured): a :class:`worker.local.LocalRuntime` runs every study of
  the database in a local process pool (also the work left pending by a previous server), unless
  ``start_local_runtime=False`` (then studies are created but wait for a server that runs them);
* distributed mode: new work batches are sent to Celery (``celery_dispatcher(settings)``); Celery
  workers run them and a separate ``scm-calib reaper`` re-dispatches lost work.

Errors are ``{"detail": "..."}`` with one line that names the field or resource, and the OpenAPI
document says so (:func:`describe_answers`): every error response is ``ErrorOut``, endpoints that
need a token carry the ``bearerAuth`` security requirement, and a request without a valid token
for such an endpoint is answered 401 before its body is read (:class:`TokenFirstMiddleware`).
"""

from __future__ import annotations

import logging
import re
from collections.abc import AsyncIterator, Iterable
from contextlib import asynccontextmanager
from importlib import metadata
from typing import Any

import sqlalchemy.exc
from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.formparsers import MultiPartException
from starlette.middleware.gzip import GZipMiddleware

from scm_core.validation_text import quoted
from services.config import Settings, get_settings
from services.store import NotFoundError, SchemaVersionError, Store
from services.studies import StudyRequestError
from services.studies.kinds.registry import KINDS

from .dashboard import FigureCache, FigureProcess, FigureWarmer, dashboard_router, mount_static
from .deps import route_needs_token
from .inference_export import NetcdfCache
from .middleware import (
    BodyLimitMiddleware,
    JsonDepthMiddleware,
    TokenFirstMiddleware,
    allowed_methods,
    api_routes,
    error_response,
)
from .params import NOT_FOUND_PARAMS
from .routes import (
    ERROR_DESCRIPTIONS,
    ERROR_HEADERS,
    cases,
    comparison,
    datasets,
    health,
    pooled,
    presets,
    studies,
    study_events,
)
from .routes.kinds import kind_router
from .schemas import ErrorOut

log = logging.getLogger(__name__)

__all__ = [
    "API_DESCRIPTION",
    "BEARER_SCHEME",
    "create_app",
    "describe_answers",
    "format_validation_errors",
]

#: largest request body of the endpoints other than uploads
JSON_BODY_LIMIT = 4 * 1024 * 1024
#: room for the multipart framing and the metadata field of an upload
UPLOAD_SLACK = 64 * 1024
#: responses shorter than this are sent as they are (gzip would not pay for its header)
GZIP_MIN_BYTES = 1024

API_DESCRIPTION = """\
Bayesian (TMCMC) calibration of Soil Contact Model parameters from single-wheel tests.

Upload SWT logs (`POST /datasets`), submit a study (`POST /studies`, a preset of the paper or a
case document), follow its progress (`GET /studies/{id}`), then read the posterior
(`.../summary`, `.../stages/{j}/samples`). Screen the soil parameters first with a Morris
sensitivity study (`POST /sensitivity`). Write endpoints need `Authorization: Bearer <token>`
(read endpoints too when the server requires it; see each operation's security): without a valid
one they answer 401, whatever the body. Errors are `{"detail": "..."}`, one line naming the field
or resource.
"""

#: name of the bearer-token security scheme in the OpenAPI document
BEARER_SCHEME = "bearerAuth"


def _version() -> str:
    try:
        return metadata.version("scm-calib")
    except metadata.PackageNotFoundError:  # pragma: no cover - source tree without install
        return "0+unknown"


# ---------------------------------------------------------------------------- error handling


def format_validation_errors(errors: list[dict[str, Any]], limit: int = 3) -> str:
    """One line from pydantic/FastAPI validation errors, each naming its location.

    Body fields are named as in the body (``dataset_ids.0``), other parameters with their
    place (``query.limit``, ``path.study_id``)."""
    parts = []
    for err in errors[:limit]:
        loc = [str(p) if len(str(p)) <= 40 else quoted(str(p)) for p in err.get("loc", ())]
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
            if item := re.match(r"item (\d+): ", msg):  # an array's item (RequestModel)
                where, msg = f"{where}.{item.group(1)}", msg[item.end() :]
            elif "input" in err and not isinstance(err["input"], dict | list | bytes):
                msg += f" (got {quoted(err['input'])})"
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


def _unparsable_body(cause: BaseException) -> str:
    """The 422 message of a body the framework could not parse (FastAPI and Starlette answer
    400): JSON that is not text, a malformed multipart form or one over its limits."""
    if isinstance(cause, UnicodeDecodeError):
        return f"body: invalid JSON: not UTF-8, UTF-16 or UTF-32 text ({cause})"
    if isinstance(cause, MultiPartException):
        return f"body: invalid multipart form: {cause.message}"
    text = " ".join(str(cause).split())
    return f"body: cannot be parsed ({type(cause).__name__}{': ' + text if text else ''})"


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(StudyRequestError)
    async def _study_request(request: Request, exc: StudyRequestError) -> JSONResponse:
        return error_response(422, str(exc))

    @app.exception_handler(StarletteHTTPException)  # also FastAPI's HTTPException
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        if exc.status_code == 405:
            own = (exc.headers or {}).get("Allow", "")  # e.g. /openapi.json, not an endpoint
            allowed = allowed_methods(request.app, request.scope) or [
                m.strip() for m in own.split(",") if m.strip()
            ]
            listed = ", ".join(allowed) or "none"
            return error_response(
                405,
                f"method {request.method} not allowed on {request.url.path} (allowed: {listed})",
                {"Allow": ", ".join(allowed)},
            )
        cause = exc.__cause__ or (None if exc.__suppress_context__ else exc.__context__)
        if exc.status_code == 400 and cause is not None:
            # the framework's answer to a body it cannot parse (FastAPI: JSON that is not
            # text; Starlette: a malformed multipart form, too many fields or files): 422,
            # as for any other invalid body (this API raises no 400 of its own)
            return error_response(422, _unparsable_body(cause))
        detail = exc.detail if isinstance(exc.detail, str) else str(jsonable_encoder(exc.detail))
        return error_response(exc.status_code, detail, getattr(exc, "headers", None))

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = list(exc.errors())
        missing = _id_out_of_range(errors)
        if missing is not None:
            return error_response(404, missing)
        return error_response(422, format_validation_errors(errors))

    @app.exception_handler(NotFoundError)
    async def _not_found(request: Request, exc: NotFoundError) -> JSONResponse:
        return error_response(404, str(exc))

    @app.exception_handler(SchemaVersionError)
    async def _schema(request: Request, exc: SchemaVersionError) -> JSONResponse:
        return error_response(503, str(exc))

    async def _database(request: Request, exc: Exception) -> JSONResponse:
        log.exception("database error on %s %s", request.method, request.url.path)
        orig = getattr(exc, "orig", None) or exc
        lines = str(orig).strip().splitlines()
        reason = f"{type(orig).__name__}: {lines[0]}" if lines else type(orig).__name__
        return error_response(
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
        return error_response(500, f"internal error ({type(exc).__name__}); see the server log")


_ERROR_REF = "#/components/schemas/ErrorOut"
#: FastAPI's default 422 body, which this API never sends
_FASTAPI_VALIDATION = ("HTTPValidationError", "ValidationError")


def _error_doc(code: int) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "description": ERROR_DESCRIPTIONS.get(code, "Error."),
        "content": {"application/json": {"schema": {"$ref": _ERROR_REF}}},
    }
    if code in ERROR_HEADERS:
        doc["headers"] = {k: dict(v) for k, v in ERROR_HEADERS[code].items()}
    return doc


def describe_answers(schema: dict[str, Any], routes: Iterable[Any], settings: Settings) -> None:
    """Make FastAPI's OpenAPI document (changed in place) say what the server sends:

    * 422 is ``ErrorOut`` (``{"detail": "<one line>"}``) everywhere, not FastAPI's
      ``HTTPValidationError`` (an array of errors), which is removed;
    * every POST documents 413 (:class:`BodyLimitMiddleware`) and, with a body, 422
      (malformed or too deep JSON);
    * the bearer-token scheme (``components.securitySchemes.bearerAuth``), required by each
      operation that needs a token under ``settings`` (writes; reads too with
      ``read_requires_token``), which documents 401 with ``WWW-Authenticate``.
    """
    components = schema.setdefault("components", {})
    schemas = components.setdefault("schemas", {})
    for name in _FASTAPI_VALIDATION:
        schemas.pop(name, None)
    if "ErrorOut" not in schemas:  # pragma: no cover - every router documents errors
        schemas["ErrorOut"] = ErrorOut.model_json_schema()
    components["securitySchemes"] = {
        BEARER_SCHEME: {
            "type": "http",
            "scheme": "bearer",
            "description": "An API token of the server (SCM_CALIB_API_TOKENS): "
            "`Authorization: Bearer <token>`.",
        }
    }
    for route in routes:
        if not isinstance(route, APIRoute) or not route.include_in_schema:
            continue
        for method in route.methods:
            op = schema.get("paths", {}).get(route.path_format, {}).get(method.lower())
            if op is None:
                continue
            responses = op.setdefault("responses", {})
            for code, response in list(responses.items()):
                ref = (
                    response.get("content", {})
                    .get("application/json", {})
                    .get("schema", {})
                    .get("$ref", "")
                )
                if ref.rsplit("/", 1)[-1] in _FASTAPI_VALIDATION:
                    responses[code] = _error_doc(int(code))
            if method in ("POST", "PUT", "PATCH"):
                responses.setdefault("413", _error_doc(413))
                if "requestBody" in op:
                    responses.setdefault("422", _error_doc(422))
            if route_needs_token(route, settings):
                op["security"] = [{BEARER_SCHEME: []}]
                responses.setdefault("401", _error_doc(401))
            op["responses"] = dict(sorted(responses.items()))


def _install_openapi(app: FastAPI, settings: Settings) -> None:
    base = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            describe_answers(base(), api_routes(app), settings)
        return app.openapi_schema  # type: ignore[return-value]

    app.openapi = openapi  # type: ignore[method-assign]


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
        # no connection held between transactions: no SIGBUS from a read-only filesystem
        st = Store.from_settings(settings, keep_connections=False) if own else store
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
            if app.state.figure_warmer is not None:
                drawer = FigureProcess(st.engine.url.render_as_string(hide_password=False))
                app.state.figure_warmer.start(st, drawer)
            log.info("scm-calib API (%s mode) on %s", mode, st.engine.url)
            yield
        finally:
            if app.state.figure_warmer is not None:
                app.state.figure_warmer.close()
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
    app.state.netcdf_cache = NetcdfCache()
    app.state.figure_warmer = FigureWarmer(FigureCache()) if settings.dashboard else None

    def limit_for(path: str) -> tuple[int, str]:
        if path.rstrip("/") == "/datasets":
            return settings.upload_max_bytes + UPLOAD_SLACK, (
                f"file: upload over the limit of {settings.upload_max_bytes} bytes "
                "(server setting SCM_CALIB_UPLOAD_MAX_BYTES)"
            )
        return JSON_BODY_LIMIT, f"body: over the limit of {JSON_BODY_LIMIT} bytes"

    app.add_middleware(JsonDepthMiddleware, max_depth=settings.max_json_depth)
    app.add_middleware(BodyLimitMiddleware, limit_for=limit_for)
    # HTML, JSON, CSV and SVG figures compress 5-10x; a client that does not ask gets them plain
    app.add_middleware(GZipMiddleware, minimum_size=GZIP_MIN_BYTES)
    app.add_middleware(TokenFirstMiddleware)  # outermost: runs first
    _install_error_handlers(app)
    routers = [
        m.router
        for m in (health, datasets, presets, cases, studies, study_events, pooled, comparison)
    ]
    routers += [kind_router(k) for k in KINDS.values() if k.http is not None]
    if settings.dashboard:
        routers.append(dashboard_router(app.state.figure_warmer))
        mount_static(app)
    for router in routers:
        app.include_router(router)
    app.state.api_routes = [
        r for router in routers for r in router.routes if isinstance(r, APIRoute)
    ]
    _install_openapi(app, settings)
    return app
