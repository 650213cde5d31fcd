"""What every repository shares: the engine, sessions, the clock and the lease policy.

Transaction boundaries: every public repository method is one transaction (``db.write()`` or
``db.read()``); it commits before returning, or rolls back and raises. Module-level helpers
that take a ``Session`` never commit: they are the building blocks that several repository
methods combine inside one transaction.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timedelta

from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

from ..engine import is_sqlite, make_sessionmaker, read_session, write_session
from ..fault_reset import FaultReset
from ..types import utcnow

__all__ = ["Database"]


@dataclass
class Database:
    """Engine + session factory + clock + lease policy, shared by the repositories.

    clock: returns an aware UTC datetime; every time written or compared by the store comes
    from it (tests inject a fake one). Lease deadlines are therefore in the clock of the
    process that leases; machines running workers need synchronised clocks (NTP), with a
    skew far below ``lease_seconds``.
    """

    engine: Engine
    clock: Callable[[], datetime] = utcnow
    lease_seconds: float = 300.0
    max_attempts: int = 3
    sessions: sessionmaker[Session] = field(init=False)
    fault_reset: FaultReset = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.lease_seconds <= 0:
            raise ValueError(f"lease_seconds must be > 0, got {self.lease_seconds!r}")
        if self.max_attempts < 1:
            raise ValueError(f"max_attempts must be >= 1, got {self.max_attempts!r}")
        self.sessions = make_sessionmaker(self.engine)
        self.fault_reset = FaultReset(self.engine, enabled=is_sqlite(self.engine))

    @property
    def dialect(self) -> str:
        return self.engine.dialect.name

    @property
    def is_postgresql(self) -> bool:
        return self.dialect == "postgresql"

    def now(self) -> datetime:
        return self.clock()

    def lease_delta(self, seconds: float | None = None) -> timedelta:
        return timedelta(seconds=self.lease_seconds if seconds is None else seconds)

    @contextmanager
    def write(self) -> Iterator[Session]:
        """A read-write transaction (BEGIN IMMEDIATE on SQLite)."""
        with self.fault_reset.use(), write_session(self.sessions) as session:
            yield session

    @contextmanager
    def read(self) -> Iterator[Session]:
        """A read-only transaction."""
        with self.fault_reset.use(), read_session(self.sessions) as session:
            yield session
