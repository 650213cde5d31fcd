"""The API's routers, one per resource."""

from __future__ import annotations

from typing import Any

from ..schemas import ErrorOut


def errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entry documenting ``{"detail": ...}`` for these status codes."""
    return {code: {"model": ErrorOut} for code in codes}
