"""The store: all repositories over one database.

>>> store = Store.open("sqlite:///scm-calib-data/scm-calib.db")   # doctest: +SKIP
>>> store.studies.list(status="running").items                      # doctest: +SKIP

:meth:`Store.open` refuses a database that is not at the migrations' head revision
(:class:`~services.store.migrate.SchemaVersionError`); run ``scm-calib db upgrade`` first.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime
from typing import TYPE_CHECKING

import sqlalchemy as sa
from sqlalchemy.engine import URL, Engine

from .engine import make_engine
from .migrate import check_revision
from .models import Heartbeat
from .repositories import (
    BatchRepository,
    Database,
    DatasetRepository,
    EventRepository,
    SampleRepository,
    StageRepository,
    StudyRepository,
)
from .types import utcnow

if TYPE_CHECKING:
    from services.config import Settings

__all__ = ["Store"]


class Store:
    """Repositories sharing one :class:`Database` (engine, clock, lease policy)."""

    def __init__(self, db: Database) -> None:
        self.db = db
        self.datasets = DatasetRepository(db)
        self.studies = StudyRepository(db)
        self.stages = StageRepository(db)
        self.batches = BatchRepository(db)
        self.samples = SampleRepository(db)
        self.events = EventRepository(db)

    @classmethod
    def open(
        cls,
        url: str | URL | Engine,
        *,
        lease_seconds: float = 300.0,
        max_attempts: int = 3,
        clock: Callable[[], datetime] = utcnow,
        check: bool = True,
        keep_connections: bool = True,
    ) -> Store:
        """A store on ``url`` (or an existing engine); checks the schema revision.

        keep_connections: False opens a SQLite connection per transaction and closes it at
        the end (the API server's store): a process that holds no connection between its
        transactions holds no map of the database's shared-memory index, and cannot be
        killed by a SIGBUS when the storage under it stops taking writes (a page of a
        read-write map written while the file is immutable or the filesystem read-only).
        """
        engine = url if isinstance(url, Engine) else make_engine(url, keep=keep_connections)
        if check:
            try:
                check_revision(engine)
            except Exception:
                if not isinstance(url, Engine):
                    engine.dispose()
                raise
        return cls(
            Database(engine, clock=clock, lease_seconds=lease_seconds, max_attempts=max_attempts)
        )

    @classmethod
    def from_settings(
        cls,
        settings: Settings | None = None,
        *,
        check: bool = True,
        keep_connections: bool = True,
    ) -> Store:
        """A store configured by the service settings (default: :func:`get_settings`);
        ``keep_connections`` as for :meth:`open`."""
        if settings is None:
            from services.config import get_settings

            settings = get_settings()
        return cls.open(
            settings.database_url,
            lease_seconds=settings.lease_seconds,
            max_attempts=settings.max_attempts,
            check=check,
            keep_connections=keep_connections,
        )

    def check_schema(self) -> str:
        """The head revision if the database is at it; raises
        :class:`~services.store.migrate.SchemaVersionError` otherwise."""
        with self.db.fault_reset.use():
            return check_revision(self.engine)

    def check_writable(self, name: str = "ready") -> str:
        """Prove the database takes writes: commit a beat of the heartbeat row ``name`` (fails
        on a read-only SQLite file, a full disk, a read-only PostgreSQL replica, role or
        session, whichever of statement or commit it fails at). Returns the schema revision;
        raises otherwise."""
        head = self.check_schema()
        for attempt in range(2):
            now = self.db.now()
            try:
                with self.db.write() as s:
                    beat = (
                        sa.update(Heartbeat)
                        .where(Heartbeat.name == name)
                        .values(beat_at=now, beats=Heartbeat.beats + 1)
                    )
                    if s.execute(beat).rowcount == 0:
                        s.add(Heartbeat(name=name, beat_at=now, beats=1))
                break
            except sa.exc.IntegrityError:  # a concurrent first beat inserted the row
                if attempt:
                    raise
        return head

    @property
    def engine(self) -> Engine:
        return self.db.engine

    def close(self) -> None:
        """Close the engine's pooled connections."""
        self.db.engine.dispose()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
