"""A filesystem that stops taking writes, all of the database's files at once (issue 73).

A read-only remount, an I/O error or a backup tool's freeze takes the SQLite database, its
write-ahead log and its shared-memory index (``-shm``) together. Connections opened during
such an outage map the index read-only, and SQLite shares one map among all of a process's
connections: without :mod:`services.store.fault_reset` a store whose connections overlap never
writes again. Here the three files are made immutable (``chattr +i``, as root) while threads
keep the store busy, and writes must work again within a few seconds of the files' return,
on the same store, with nothing stored before the outage lost.

The store's own connections are closed before the outage starts: a page of a read-write map
that SQLite writes while the file is immutable is a SIGBUS, which kills the process (the
embedded server's supervisors replace such processes: ``tests/service``). A helper process
holds the database open, as the server's other processes do, so that SQLite keeps the
write-ahead log and the index in place.
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from test_store_write_outage import chattr_works

from services.store import Store, upgrade
from services.store.engine import is_write_fault
from services.store.models import Event

#: writes must work again within this long of the files' return (each failed transaction asks
#: for a renewal; the next one, after the transactions in flight end, opens fresh connections)
RECOVERY_S = 5.0


@pytest.fixture
def database(tmp_path: Path) -> Iterator[Path]:
    if not chattr_works(tmp_path):
        pytest.skip("a filesystem outage needs root and chattr on this filesystem")
    path = tmp_path / "outage.db"
    upgrade(f"sqlite:///{path}")
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sqlite3, sys; c = sqlite3.connect(sys.argv[1]); "
            "c.execute('SELECT count(*) FROM sqlite_master').fetchall(); "
            "print('open', flush=True); sys.stdin.read()",
            str(path),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout.readline().strip() == "open"
    try:
        yield path
    finally:
        files = [str(p) for p in _files(path)]
        subprocess.run(["chattr", "-i", *files], capture_output=True)
        holder.stdin.close()
        holder.wait(timeout=30)
        holder.stdout.close()


def _files(path: Path) -> list[Path]:
    return [path, path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")]


def _beat(store: Store) -> str | None:
    """A heartbeat's write: None if it was stored, else the driver's one-line reason (a
    write fault, asserted; the exception is not kept: its traceback would keep the failed
    connection's statements alive)."""
    try:
        store.check_writable("outage-test")
    except sa.exc.DBAPIError as exc:
        assert is_write_fault(exc), exc
        return str(exc.orig)
    return None


def _count(store: Store) -> int:
    with store.db.read() as s:
        return s.execute(sa.select(sa.func.count()).select_from(Event)).scalar_one()


def test_a_store_writes_again_after_all_its_files_stopped_taking_writes(database: Path) -> None:
    url = f"sqlite:///{database}"
    store = Store.open(url)
    try:
        for _ in range(3):
            _beat(store)
        rows_before = _count(store)
        with store.db.read() as s:
            beats_before = s.execute(
                sa.text("SELECT beats FROM heartbeats WHERE name = 'outage-test'")
            ).scalar_one()
        assert beats_before == 3
        store.close()  # no read-write map of the index in this process (see the docstring)
        files = _files(database)
        assert all(p.exists() for p in files), "the helper keeps the log and the index"

        stop = threading.Event()
        read_errors: list[str] = []

        def keep_reading() -> None:  # overlapping connections, as a server's threads make
            while not stop.is_set():
                try:
                    _count(store)
                except Exception as exc:  # kept as text: a traceback keeps its connection
                    read_errors.append(f"{type(exc).__name__}: {exc}")
                time.sleep(0.002)

        readers = [threading.Thread(target=keep_reading) for _ in range(3)]
        subprocess.run(["chattr", "+i", *map(str, files)], check=True)
        try:
            for t in readers:
                t.start()
            refused = 0
            for _ in range(5):
                assert _beat(store) is not None, "a write was stored during the outage"
                refused += 1
                time.sleep(0.1)
            assert _count(store) == rows_before  # reads go on during the outage
        finally:
            subprocess.run(["chattr", "-i", *map(str, files)], check=True)
        back = time.monotonic()
        failures = 0
        while (why := _beat(store)) is not None:
            failures += 1
            assert time.monotonic() - back < RECOVERY_S, (
                f"no write {RECOVERY_S} s after the files' return ({failures} failed): {why}"
            )
            time.sleep(0.05)
        recovered_s = time.monotonic() - back
        for _ in range(20):  # and every write after it, with the readers still going
            assert _beat(store) is None
        stop.set()
        for t in readers:
            t.join()
        assert not read_errors, read_errors[:3]
        with store.db.read() as s:
            beats = s.execute(
                sa.text("SELECT beats FROM heartbeats WHERE name = 'outage-test'")
            ).scalar_one()
        assert beats == beats_before + 21  # nothing before the outage lost, none counted twice
        assert _count(store) == rows_before
        assert store.db.fault_reset.resets >= 1
        print(
            f"{refused} writes refused during the outage; a write {recovered_s:.3f} s after it "
            f"({failures} failed), {store.db.fault_reset.resets} renewal(s)"
        )
    finally:
        store.close()
