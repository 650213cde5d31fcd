"""A batch stopped by Ctrl-C is an interrupt, not a failure, also when a library wraps the
KeyboardInterrupt (numba raises a SystemError caused by it): execute_batch raises
KeyboardInterrupt, logs nothing and leaves the lease for its owner to give back uncounted.
A command's Ctrl-C stops its simulations at once and its store work at a safe point."""

from __future__ import annotations

import os
import signal
import time

import pytest
from store_fixtures import *  # noqa: F403 (the store fixtures: store, toy, clock ...)

from worker.interrupt import Interrupts
from worker.orchestrator import ContextCache, execute_batch, is_interrupt


class _Interrupted:
    model_function = None

    def compute(self, store, lease, model_function):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("a compiled call returned with an exception set") from exc


def test_is_interrupt_sees_through_wrapping() -> None:
    wrapped = SystemError("x")
    wrapped.__cause__ = KeyboardInterrupt()
    assert is_interrupt(wrapped) and is_interrupt(KeyboardInterrupt())
    assert not is_interrupt(RuntimeError("x")) and not is_interrupt(None)


def test_a_wrapped_interrupt_leaves_the_lease_to_be_given_back(store, toy, caplog) -> None:
    sid = store.studies.create(toy.spec()).id
    store.studies.start(sid, toy.batches(toy.n_samples))
    key = store.batches.list(sid, 0)[0].key
    cache = ContextCache()
    cache.get = lambda store, study_id: _Interrupted()  # type: ignore[method-assign]
    with pytest.raises(KeyboardInterrupt):
        execute_batch(store, key, cache, None, worker="here/h/1")
    assert "failed" not in caplog.text
    batch = store.batches.get(key)
    assert batch.status == "leased" and batch.attempts == 1
    assert store.batches.give_back("here/h") == [key]
    assert store.batches.get(key).attempts == 0


def _sigint() -> None:
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.05)  # the handler runs in the main thread at its next bytecode


def test_ctrl_c_stops_an_open_section_at_once_and_defers_elsewhere() -> None:
    """A command's Ctrl-C (worker.interrupt.Interrupts): inside an open section (simulating,
    waiting) SIGINT raises KeyboardInterrupt there; elsewhere (store work) it is only recorded
    and raised at the next check or section; the handler before is back afterwards."""
    before = signal.getsignal(signal.SIGINT)
    with Interrupts().installed() as stop:
        with pytest.raises(KeyboardInterrupt), stop.open():
            _sigint()
            pytest.fail("not stopped inside the open section")
        stop.requested = False
        _sigint()  # outside: recorded, not raised here
        assert stop.requested
        with pytest.raises(KeyboardInterrupt), stop.open():  # raised on entering the next
            pytest.fail("entered a section after Ctrl-C")
        with pytest.raises(KeyboardInterrupt):
            stop.check()
    assert signal.getsignal(signal.SIGINT) is before


def test_a_run_that_ignores_sigint_keeps_ignoring_it() -> None:
    """A job a shell started in the background has SIGINT ignored: a run leaves it so."""
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with Interrupts().installed() as stop, stop.open():
            _sigint()
            assert not stop.requested
    finally:
        signal.signal(signal.SIGINT, before)
