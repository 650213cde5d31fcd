"""A batch stopped by Ctrl-C is an interrupt, not a failure, also when a library wraps the
KeyboardInterrupt (numba raises a SystemError caused by it): execute_batch raises
KeyboardInterrupt, logs nothing and leaves the lease for its owner to give back uncounted."""

from __future__ import annotations

import pytest
from store_fixtures import *  # noqa: F403 (the store fixtures: store, toy, clock ...)

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
