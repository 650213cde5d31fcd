"""How many uploads one API process parses at once (``SCM_CALIB_MAX_CONCURRENT_UPLOADS``)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import HTTPException

from services.config import Settings

#: seconds a client is asked to wait when the upload slots are full
UPLOAD_RETRY_AFTER_S = 5


class UploadSlots:
    """At most ``n`` uploads in progress; past that 429 with Retry-After. Used from the event
    loop thread only, so a plain counter suffices."""

    def __init__(self, n: int, retry_after_s: int = UPLOAD_RETRY_AFTER_S) -> None:
        self.limit = n
        self.busy = 0
        self.retry_after_s = retry_after_s

    @asynccontextmanager
    async def hold(self) -> AsyncIterator[None]:
        if self.busy >= self.limit:
            raise HTTPException(
                429,
                f"{self.limit} uploads are being processed, the most at once "
                "(server setting SCM_CALIB_MAX_CONCURRENT_UPLOADS); retry later",
                headers={"Retry-After": str(self.retry_after_s)},
            )
        self.busy += 1
        try:
            yield
        finally:
            self.busy -= 1


def upload_slots(app: Any, settings: Settings) -> UploadSlots:
    """The application's upload slots (made on first use)."""
    slots = getattr(app.state, "upload_slots", None)
    if slots is None:
        slots = app.state.upload_slots = UploadSlots(settings.max_concurrent_uploads)
    return slots
