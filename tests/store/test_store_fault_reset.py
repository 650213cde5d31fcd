"""The renewal of a store's connections after a storage fault (services.store.fault_reset)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import sqlalchemy as sa
from store_fixtures import transaction_held_open

from services.store import upgrade
from services.store.engine import make_engine
from services.store.fault_reset import FaultReset


def _engine(tmp_path: Path) -> sa.Engine:
    url = f"sqlite:///{tmp_path / 'reset.db'}"
    upgrade(url)
    return make_engine(url)


def test_a_renewal_waits_for_the_transactions_in_flight_and_closes_every_connection(
    tmp_path: Path,
) -> None:
    engine = _engine(tmp_path)
    reset = FaultReset(engine, drain_timeout=5.0)
    try:
        held, release = threading.Event(), threading.Event()
        order: list[str] = []

        def in_flight() -> None:
            with reset.use(), engine.connect() as conn:
                conn.execute(sa.text("SELECT 1"))
                held.set()
                release.wait(10)
                order.append("in flight ended")

        t = threading.Thread(target=in_flight)
        t.start()
        held.wait(10)
        reset.fault()
        threading.Timer(0.3, release.set).start()
        t0 = time.monotonic()
        with reset.use():  # waits for the other transaction, then renews
            order.append("next began")
            waited = time.monotonic() - t0
            with engine.connect() as conn:
                assert conn.execute(sa.text("SELECT 1")).scalar_one() == 1
        t.join()
        assert order == ["in flight ended", "next began"]
        assert 0.2 < waited < 5.0, waited
        assert reset.resets == 1 and reset.stuck_for() == 0.0
        # a nested use in the same thread does not wait for itself
        reset.fault()
        with reset.use(), reset.use():
            pass
        assert reset.resets == 2
    finally:
        engine.dispose()


def test_a_drain_that_does_not_come_lets_work_go_on_and_says_so(tmp_path: Path) -> None:
    engine = _engine(tmp_path)
    reset = FaultReset(engine, drain_timeout=0.2)
    try:
        with transaction_held_open(reset) as end:
            reset.fault()
            t0 = time.monotonic()
            with reset.use():  # not held up for good: goes on after the drain timeout
                pass
            assert 0.15 < time.monotonic() - t0 < 2.0
            assert reset.resets == 0 and reset.stuck_for() > 0.15
            end()
        with reset.use():
            pass
        assert reset.resets == 1 and reset.stuck_for() == 0.0
    finally:
        engine.dispose()


def test_a_storage_fault_inside_a_use_asks_for_a_renewal_and_others_do_not(
    tmp_path: Path,
) -> None:
    engine = _engine(tmp_path)
    reset = FaultReset(engine)
    try:
        try:
            with reset.use():
                raise sa.exc.IntegrityError("INSERT", {}, Exception("UNIQUE constraint failed"))
        except sa.exc.IntegrityError:
            pass
        with reset.use():
            pass
        assert reset.resets == 0
        readonly = Exception("attempt to write a readonly database")
        err = sa.exc.OperationalError("BEGIN", {}, readonly)
        try:
            with reset.use():
                raise err
        except sa.exc.OperationalError:
            pass
        with reset.use():
            pass
        assert reset.resets == 1
    finally:
        engine.dispose()
