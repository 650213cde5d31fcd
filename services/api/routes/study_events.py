"""A study's progress as server-sent events: ``GET /studies/{id}/stream``.

The stream sends the study (as ``GET /studies/{id}`` gives it) at once and again whenever its
version changes, looked at every :data:`CHECK_SECONDS` (one indexed read; the read runs on a
worker thread, so a stream holds no thread between looks), and ends after the study has ended
or after :data:`STREAM_SECONDS` (the client reconnects). A comment line every
:data:`KEEPALIVE_SECONDS` keeps proxies from closing an idle stream. For scripts that wait on a
study (``SCMCalibClient.watch``); the dashboard polls instead (docs/dashboard.md, "Polling and
server-sent events", with the measurements of both).
"""

from __future__ import annotations

import time
from collections.abc import AsyncIterator

import anyio
from fastapi import APIRouter, Depends, Request
from fastapi.responses import StreamingResponse

from services.store import Store
from services.store.models import STUDY_ACTIVE

from ..deps import StoreDep, require_read
from ..params import StudyId
from ..views import study_out
from . import errors

router = APIRouter(prefix="/studies", tags=["studies"], dependencies=[Depends(require_read)])

#: seconds between two looks at the study's version
CHECK_SECONDS = 0.25
#: seconds between keep-alive comments on a quiet stream
KEEPALIVE_SECONDS = 15.0
#: a stream ends after this long even if the study runs on (EventSource reconnects)
STREAM_SECONDS = 3600.0


#: one event of the stream (the OpenAPI schema of an event-stream describes its events)
_EVENT_SCHEMA = {
    "type": "object",
    "properties": {
        "event": {"type": "string", "enum": ["study"]},
        "id": {"type": "string", "description": "the study's version"},
        "data": {"type": "string", "description": "the study's JSON (StudyOut)"},
    },
    "required": ["event", "id", "data"],
}


@router.get(
    "/{study_id}/stream",
    summary="The study's progress as server-sent events",
    response_class=StreamingResponse,
    responses={
        200: {
            "content": {"text/event-stream": {"schema": _EVENT_SCHEMA}},
            "description": "event: study, data: the study as GET /studies/{id} gives it; sent "
            "at once and on every change, until the study has ended",
        },
        **errors(401, 404),
    },
)
def study_events(study_id: StudyId, request: Request, store: StoreDep) -> StreamingResponse:
    """Server-sent events of the study: ``event: study`` with the study's JSON (``id:`` its
    version) at once and whenever it changes; the stream ends once the study has ended."""
    store.studies.get(study_id)  # 404 before the stream starts
    return StreamingResponse(
        _events(store, study_id, request),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
    )


def _event(store: Store, study_id: int) -> tuple[str, int, bool]:
    """(the event, the version it shows, whether the study is still active)."""
    study = store.studies.get(study_id)
    body = study_out(store, study).model_dump_json()
    text = f"id: {study.version}\nevent: study\ndata: {body}\n\n"
    return text, study.version, study.status in STUDY_ACTIVE


async def _events(store: Store, study_id: int, request: Request) -> AsyncIterator[str]:
    text, version, active = await anyio.to_thread.run_sync(_event, store, study_id)
    yield text
    start = last_sent = time.monotonic()
    while active and time.monotonic() - start < STREAM_SECONDS:
        await anyio.sleep(CHECK_SECONDS)
        if await request.is_disconnected():
            return
        if await anyio.to_thread.run_sync(store.studies.version, study_id) != version:
            text, version, active = await anyio.to_thread.run_sync(_event, store, study_id)
            yield text
            last_sent = time.monotonic()
        elif time.monotonic() - last_sent >= KEEPALIVE_SECONDS:
            yield ": keep-alive\n\n"
            last_sent = time.monotonic()
