"""A database that stops taking writes for a moment (issue 46), on SQLite and PostgreSQL.

The outage is real: on SQLite the database file and its write-ahead log are made immutable
(``chattr +i``, as root: file modes do not stop root); on PostgreSQL the database is switched to
``default_transaction_read_only`` and its sessions are ended, so the pool reconnects into
read-only sessions (as after a fail-over to a replica). Both leave connections that stay
read-only after the fault unless they are discarded.

* the result of a batch computed during an outage is stored within ``RETRY_LONGEST_S`` (plus
  a margin for the write itself) of the database taking writes again, while the lease holds;
* when the lease runs out first, the worker gives up; the reaper takes the batch back and the
  study completes;
* readiness (``Store.check_writable``) commits a real write: it fails during the outage, and
  succeeds right after it on the same store (the read-only connections are not reused).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from test_store_sensitivity import CASE, LOG

from scm_core.calibration import MorrisSettings
from scm_core.signals import load_log
from services.config import Settings
from services.store import Store
from services.store.engine import is_transient, is_write_fault
from services.studies import start_study
from services.studies.kinds.sensitivity import sensitivity_spec
from worker.orchestrator import (
    RETRY_LONGEST_S,
    ContextCache,
    execute_batch,
    reap_once,
    retry_while_transient,
)

#: the write itself after the outage: a transaction and, on PostgreSQL, a reconnection
WRITE_MARGIN_S = 1.5


def chattr_works(tmp: Path) -> bool:
    """Root, chattr, and a filesystem that takes the immutable flag (tmp: a folder on it)."""
    if shutil.which("chattr") is None or os.geteuid() != 0:
        return False
    probe = tmp / "chattr-probe"
    probe.write_bytes(b"")
    ok = subprocess.run(["chattr", "+i", str(probe)], capture_output=True).returncode == 0
    subprocess.run(["chattr", "-i", str(probe)], capture_output=True)
    return ok


class Outage:
    """Switches the test database's writes off and on (see the module docstring)."""

    def __init__(self, db_url: str, request: pytest.FixtureRequest, tmp: Path) -> None:
        self.url = sa.make_url(db_url)
        self.sqlite = self.url.get_backend_name() == "sqlite"
        if self.sqlite:
            if not chattr_works(tmp):
                pytest.skip("a SQLite write outage needs root and chattr on this filesystem")
            self.admin = None
        else:
            self.admin = request.getfixturevalue("pg_server").engine
        self.on = False

    def _files(self) -> list[str]:
        # not the -shm file: SQLite maps it, and an immutable mapped page is a SIGBUS
        path = Path(self.url.database)
        return [str(p) for p in (path, path.with_name(path.name + "-wal")) if p.exists()]

    def start(self) -> None:
        self.on = True
        if self.sqlite:
            subprocess.run(["chattr", "+i", *self._files()], check=True)
            return
        name = self.url.database
        with self.admin.connect() as conn:
            conn.execute(sa.text(f'ALTER DATABASE "{name}" SET default_transaction_read_only = on'))
            conn.execute(
                sa.text(
                    "SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
                    "WHERE datname = :name AND pid <> pg_backend_pid()"
                ),
                {"name": name},
            )

    def stop(self) -> None:
        if not self.on:
            return
        self.on = False
        if self.sqlite:
            subprocess.run(["chattr", "-i", *self._files()], check=True)
            return
        with self.admin.connect() as conn:
            conn.execute(
                sa.text(
                    f'ALTER DATABASE "{self.url.database}" SET default_transaction_read_only = off'
                )
            )


@pytest.fixture
def outage(db_url: str, request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Outage]:
    o = Outage(db_url, request, tmp_path)
    try:
        yield o
    finally:
        o.stop()


class _FaultAfterCompute:
    """A study's computation that starts the outage when a batch's result is computed (before
    the worker stores it) and ends it ``seconds`` later from a timer; ``ended`` is the
    monotonic time the outage ended."""

    def __init__(self, run, outage: Outage, seconds: float) -> None:
        self._run, self._outage, self._seconds = run, outage, seconds
        self.started: float | None = None
        self.ended: float | None = None
        self.timer: threading.Timer | None = None

    def __getattr__(self, name: str):
        return getattr(self._run, name)

    def compute(self, store, lease, model_function):
        result = self._run.compute(store, lease, model_function)
        if self.timer is None:
            self._outage.start()
            self.started = time.monotonic()
            self.timer = threading.Timer(self._seconds, self._end)
            self.timer.start()
        return result

    def _end(self) -> None:
        self._outage.stop()
        self.ended = time.monotonic()


class _Cache(ContextCache):
    def __init__(self, wrap: Callable) -> None:
        super().__init__()
        self._wrap = wrap
        self.wrapper = None

    def get(self, store, study_id):
        if self.wrapper is None:
            self.wrapper = self._wrap(super().get(store, study_id))
        return self.wrapper


def _morris_study(store: Store) -> tuple[int, list]:
    raw = LOG.read_bytes()
    meta = json.loads(LOG.with_suffix(".json").read_text())
    rec, _ = store.datasets.add(load_log(raw, metadata=meta), raw, meta=meta)
    morris = MorrisSettings(r=3, levels=4, seed=9)
    spec = sensitivity_spec(store, Settings(), CASE, rec.id, morris, batch_size=4)
    study = store.studies.create(spec)
    start_study(store, study.id, None)
    return study.id, [b.key for b in store.batches.list(study.id, 0)]


def test_a_result_computed_during_an_outage_is_stored_as_soon_as_writes_return(
    store: Store, outage: Outage
) -> None:
    study_id, keys = _morris_study(store)
    cache = _Cache(lambda run: _FaultAfterCompute(run, outage, seconds=3.0))
    outcome = execute_batch(store, keys[0], cache, None)
    stored = time.monotonic()
    cache.wrapper.timer.join()
    assert outcome == "stored"
    stall = stored - cache.wrapper.ended
    assert stall < RETRY_LONGEST_S + WRITE_MARGIN_S, f"stored {stall:.2f} s after the outage"
    print(f"result stored {stall:.2f} s after the outage ({outage.url.get_backend_name()})")
    assert store.batches.get(keys[0]).status == "done"
    # the rest of the study runs on the same store (no restart), and completes
    outcomes = [execute_batch(store, k, cache, None) for k in keys[1:]]
    assert outcomes == ["stored"] * (len(keys) - 1)
    done = store.studies.get(study_id)
    assert done.status == "completed" and done.model_runs == 21


def test_a_lease_that_runs_out_during_the_outage_is_taken_back(
    db_url: str, clock, outage: Outage
) -> None:
    """Lease 1 s, outage 3 s: the worker stops retrying when its lease ends (the batch is
    neither stored nor lost); after the outage the reaper takes the batch back and it runs."""
    store = Store.open(db_url, lease_seconds=1.0, max_attempts=3, clock=clock)
    try:
        study_id, keys = _morris_study(store)
        cache = _Cache(lambda run: _FaultAfterCompute(run, outage, seconds=3.0))
        with pytest.raises(sa.exc.DBAPIError) as info:
            execute_batch(store, keys[0], cache, None)
        gave_up = time.monotonic() - cache.wrapper.started
        assert is_transient(info.value)
        # it gave up while the outage lasted (at its lease's end, 1 s, plus the last failed
        # write and release on a loaded machine), not when writes came back at 3 s
        assert cache.wrapper.ended is None, f"gave up {gave_up:.2f} s in, after the outage"
        cache.wrapper.timer.join()
        assert store.batches.get(keys[0]).status == "leased"  # release could not be written
        clock.advance(2.0)
        reap_once(store, ContextCache(), _NoDispatch(), redispatch_after=0.0)
        assert store.batches.get(keys[0]).status == "pending"
        outcomes = [execute_batch(store, k, ContextCache(), None) for k in keys]
        assert outcomes == ["stored"] * len(keys)
        assert store.studies.get(study_id).status == "completed"
    finally:
        store.close()


class _NoDispatch:
    def dispatch(self, keys) -> None:
        pass


def test_readiness_commits_a_write_and_recovers_without_a_restart(
    store: Store, db_url: str, outage: Outage
) -> None:
    assert store.check_writable()
    outage.start()
    during = Store.open(db_url)  # connects during the outage (read-only connections)
    try:
        for s in (store, during):
            with pytest.raises(sa.exc.DBAPIError) as info:
                s.check_writable()
            assert is_write_fault(info.value)
        outage.stop()
        for s in (store, during):
            assert s.check_writable()  # the read-only connections were discarded
        with store.db.read() as s:
            beats = s.execute(sa.text("SELECT beats FROM heartbeats WHERE name = 'ready'"))
            assert beats.scalar_one() == 3
    finally:
        during.close()


def test_retry_raises_at_once_what_a_retry_cannot_fix() -> None:
    calls = []

    def bad() -> None:
        calls.append(1)
        raise sa.exc.IntegrityError("INSERT", {}, Exception("duplicate key"))

    with pytest.raises(sa.exc.IntegrityError):
        retry_while_transient(bad, time.monotonic() + 60.0, "test")
    assert len(calls) == 1

    flaky = iter([sa.exc.OperationalError("UPDATE", {}, Exception("database is locked"))] * 3)

    def busy() -> str:
        exc = next(flaky, None)
        if exc is not None:
            raise exc
        return "stored"

    assert retry_while_transient(busy, time.monotonic() + 60.0, "test", first_wait=0.01) == "stored"
