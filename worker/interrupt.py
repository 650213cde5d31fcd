"""Ctrl-C for a study run in this process (the command line's): at once while it simulates or
waits, at the next safe point while it talks to the store.

Python raises KeyboardInterrupt wherever the main thread happens to be. Inside the store's
code that can leave a transaction open (the run's last writes then fail with SQLite's
"database is locked" or "cannot commit transaction"), and inside a garbage-collection callback
the exception is printed and dropped, so the run goes on as if nothing had been asked
(seen in about one in ten tries of ``tests/calibration/test_calib_cli.py``'s Ctrl-C test).
:class:`Interrupts` takes SIGINT instead: it records the request, and raises only inside
sections that hold no store transaction (:meth:`Interrupts.open`: a batch's simulations, a
pool run's waits); everywhere else the run raises at its next check (:meth:`Interrupts.check`:
each turn of its loop, the next simulation). Either way the caller sees KeyboardInterrupt.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["Interrupts"]


class Interrupts:
    """A run's Ctrl-C (see the module): :meth:`installed` for its duration."""

    def __init__(self) -> None:
        self.requested = False
        self._open = 0

    def _on_sigint(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True
        if self._open:
            raise KeyboardInterrupt

    @contextlib.contextmanager
    def installed(self) -> Iterator[Interrupts]:
        """Take SIGINT while the block runs (in the main thread, unless SIGINT is ignored, as
        for a job a shell started in the background; elsewhere nothing changes)."""
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        before = signal.getsignal(signal.SIGINT)
        if before is signal.SIG_IGN:
            yield self
            return
        signal.signal(signal.SIGINT, self._on_sigint)
        try:
            yield self
        finally:
            signal.signal(signal.SIGINT, before)

    @contextlib.contextmanager
    def open(self) -> Iterator[None]:
        """A section Ctrl-C may stop at once (it holds no store transaction)."""
        self.check()
        self._open += 1
        try:
            yield
        finally:
            self._open -= 1

    def check(self) -> None:
        """Raise KeyboardInterrupt if Ctrl-C was pressed."""
        if self.requested:
            raise KeyboardInterrupt
