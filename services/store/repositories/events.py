"""The append-only event log: what happened to a study (or, with study_id None, the service).

Appending a study's event is a change of its state: the study's ``version`` goes up and its
``updated_at`` moves, in the same transaction (:func:`touch_study`). Callers that also hold a
stage's row lock take it before appending (lock order: batch, stage, study).

Order: by ``id``, which is allocated at insert. Concurrent writers may commit in a different
order than their ids, so a poller reading ``after_id`` should re-read a short overlap window
(or poll by study, where the orchestrator's transactions are serialised by the stage lock).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from scm_core.jsondoc import encode_float

from ..models import Event, Study
from ..records import EventRecord
from .base import Database

__all__ = ["EventRepository", "append_event", "touch_study"]


def _record(e: Event) -> EventRecord:
    return EventRecord(
        id=e.id,
        study_id=e.study_id,
        created_at=e.created_at,
        kind=e.kind,
        payload=dict(e.payload or {}),
    )


def touch_study(session: Session, study_id: int, at: datetime) -> None:
    """Raise the study's version and set its ``updated_at`` (caller's transaction)."""
    session.execute(
        sa.update(Study)
        .where(Study.id == study_id)
        .values(version=Study.version + 1, updated_at=at)
        .execution_options(synchronize_session=False)
    )


def append_event(
    session: Session,
    study_id: int | None,
    kind: str,
    payload: Mapping[str, Any] | None,
    at: datetime,
) -> Event:
    """Add one event in the caller's transaction (flushed, so it has its id); a study's event
    raises the study's version. ``payload``: a flat record of JSON values, whose floats may be
    non-finite (written as "nan", "inf", "-inf")."""
    if study_id is not None:
        touch_study(session, study_id, at)
    body = {k: encode_float(v) if isinstance(v, float) else v for k, v in (payload or {}).items()}
    event = Event(study_id=study_id, kind=kind, payload=body, created_at=at)
    session.add(event)
    session.flush()
    return event


class EventRepository:
    def __init__(self, db: Database) -> None:
        self.db = db

    def append(
        self, study_id: int | None, kind: str, payload: Mapping[str, Any] | None = None
    ) -> EventRecord:
        """Append one event (its own transaction)."""
        with self.db.write() as s:
            return _record(append_event(s, study_id, kind, payload, self.db.now()))

    def list(
        self,
        study_id: int | None = None,
        *,
        after_id: int | None = None,
        kinds: Sequence[str] | None = None,
        limit: int = 100,
    ) -> list[EventRecord]:
        """Events in append order (ascending id), optionally of one study, after an id."""
        q = sa.select(Event).order_by(Event.id).limit(max(int(limit), 0))
        if study_id is not None:
            q = q.where(Event.study_id == study_id)
        if after_id is not None:
            q = q.where(Event.id > after_id)
        if kinds:
            q = q.where(Event.kind.in_(list(kinds)))
        with self.db.read() as s:
            return [_record(e) for e in s.scalars(q)]
