"""The API's routers, one per resource."""

from __future__ import annotations

import copy
from typing import Any

from ..schemas import ErrorOut

#: what each documented error status means in this API
ERROR_DESCRIPTIONS = {
    401: "Missing or invalid API token.",
    404: "No such resource.",
    409: "The resource is not in a state that allows this.",
    413: "Request body or upload over the size limit.",
    415: "Unsupported Content-Type.",
    422: "Invalid request: the message names the field.",
    429: "Too many such requests at once: retry after Retry-After seconds.",
    503: "The database or the service is unavailable.",
}

#: response headers sent with an error status (all of them always)
ERROR_HEADERS: dict[int, dict[str, dict[str, Any]]] = {
    401: {
        "WWW-Authenticate": {
            "description": "The authentication scheme to use: Bearer.",
            "required": True,
            "schema": {"type": "string"},
        }
    },
    429: {
        "Retry-After": {
            "description": "Seconds to wait before retrying.",
            "required": True,
            "schema": {"type": "integer", "minimum": 0},
        }
    },
}


def error_response(code: int) -> dict[str, Any]:
    """OpenAPI ``responses`` entry of one error status: ``{"detail": ...}`` (ErrorOut), with
    its description and the headers sent with it (``WWW-Authenticate`` with 401,
    ``Retry-After`` with 429)."""
    entry: dict[str, Any] = {"model": ErrorOut}
    if code in ERROR_DESCRIPTIONS:
        entry["description"] = ERROR_DESCRIPTIONS[code]
    if code in ERROR_HEADERS:
        entry["headers"] = copy.deepcopy(ERROR_HEADERS[code])
    return entry


def errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entry documenting ``{"detail": ...}`` for these status codes
    (with their headers: ``WWW-Authenticate`` for 401, ``Retry-After`` for 429)."""
    return {code: error_response(code) for code in codes}
