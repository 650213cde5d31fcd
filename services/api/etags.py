"""Conditional GETs: weak ETags from study versions, 304 when nothing changed.

A study's ``version`` rises with every change of its state (a batch or stage finishing, its
status changing: :func:`services.store.repositories.events.touch_study`), so an ETag made of the
versions a response depends on says whether it could have changed. The check reads the
studies table only (:meth:`~services.store.repositories.studies.StudyRepository.version`,
``list_versions``); a matching ``If-None-Match`` is answered 304 before stages, batches or
samples are read. Tags are weak (``W/"..."``): fields derived from the clock (elapsed time,
rate, ETA) are those of the last change.
"""

from __future__ import annotations

import hashlib
from typing import Any

from fastapi import Request, Response

__all__ = ["etag_of", "not_modified", "set_etag"]


def etag_of(*parts: Any) -> str:
    """A weak ETag naming ``parts`` (the resource, its query and the versions it depends on)."""
    digest = hashlib.blake2b(repr(parts).encode(), digest_size=12).hexdigest()
    return f'W/"{digest}"'


def _matches(header: str, tag: str) -> bool:
    """``If-None-Match`` uses the weak comparison (RFC 9110, 13.1.2)."""
    if header.strip() == "*":
        return True
    opaque = tag.removeprefix("W/")
    return any(t.strip().removeprefix("W/") == opaque for t in header.split(","))


def not_modified(request: Request, tag: str) -> Response | None:
    """A 304 answer if the request's ``If-None-Match`` matches ``tag``, else None."""
    header = request.headers.get("if-none-match")
    if header and _matches(header, tag):
        return Response(status_code=304, headers={"ETag": tag, "Cache-Control": "no-cache"})
    return None


def set_etag(response: Response, tag: str) -> None:
    """Send ``tag`` with a full answer; ``no-cache``: caches revalidate every time."""
    response.headers["ETag"] = tag
    response.headers["Cache-Control"] = "no-cache"
