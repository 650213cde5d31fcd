"""The embedded server's process pool, supervised: one pipe per process, deaths seen at once.

Every method is called from one thread, the runtime's long-lived loop thread, so every process
is started (forked, then exec'd: the ``spawn`` method) by that thread. This matters on Linux:
the parent-death signal that takes a pool process down with the server
(``PR_SET_PDEATHSIG``, :func:`worker.runtime.exit_with_parent`) fires when the *thread* that
forked the process ends, so processes forked lazily from short-lived request threads died
silently a few seconds after those threads were retired.

A process that dies (killed, out of memory, a crash in compiled code) is reported with the batch
it was running and replaced; the other processes keep running (unlike
``concurrent.futures.ProcessPoolExecutor``, where one death breaks the whole pool).
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import signal
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any

from services.store.records import BatchKey

log = logging.getLogger(__name__)

#: a slot whose process died waits this long before it is started again, doubling up to
#: RESTART_BACKOFF_MAX_S while processes keep dying at start
RESTART_BACKOFF_S = 0.5
RESTART_BACKOFF_MAX_S = 30.0
#: a process that ran this long is healthy again: its slot's backoff is reset
HEALTHY_AFTER_S = 60.0


def death_reason(exitcode: int | None) -> str:
    """A dead process's exit code in words: the signal that killed it, with what a SIGBUS
    means here."""
    if exitcode is None or exitcode >= 0:
        return f"exit code {exitcode}"
    try:
        name = signal.Signals(-exitcode).name
    except ValueError:
        return f"killed by signal {-exitcode}"
    if -exitcode == signal.SIGBUS:
        return (
            f"killed by {name}: a mapped page of the database's files could not be written, "
            "the storage under it failed"
        )
    return f"killed by {name}"


@dataclass
class _Slot:
    index: int
    process: Any = None  # multiprocessing.Process
    conn: Connection | None = None
    ready: bool = False
    key: BatchKey | None = None
    started_at: float = 0.0
    next_start: float = 0.0
    backoff: float = RESTART_BACKOFF_S

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.is_alive()


@dataclass
class PoolEvent:
    """What :meth:`SupervisedPool.wait` saw: a batch finished (``outcome`` "stored",
    "duplicate", "skipped", "rejected" or "error: ..."), or a process died (``died``) with
    the batch it held, if any."""

    pid: int
    key: BatchKey | None
    outcome: str | None = None
    died: bool = False
    exitcode: int | None = None


@dataclass(frozen=True)
class Health:
    """Readiness of the pool (and of the runtime around it): ok, and one line saying why."""

    ok: bool
    detail: str


class SupervisedPool:
    """``size`` worker processes running ``target(args, key)`` for one batch key at a time.

    target: the process main (:func:`worker.runtime.pool_process_main`), started as
    ``target(conn, args)``; it sends ``("ready", pid)`` once warmed up, then answers every
    key it receives with ``("done", key, outcome)``; ``None`` asks it to exit.
    """

    def __init__(self, size: int, target: Callable[..., None], args: tuple) -> None:
        if size < 1:
            raise ValueError(f"a pool needs at least one process, got {size}")
        self._ctx = multiprocessing.get_context("spawn")
        self._target = target
        self._args = args
        self._slots = [_Slot(i) for i in range(size)]
        self.restarts = 0
        self._deaths: deque[float] = deque(maxlen=64)
        self.last_death: str | None = None

    # ---- processes -----------------------------------------------------------------------

    def _start(self, slot: _Slot) -> None:
        parent, child = self._ctx.Pipe(duplex=True)
        proc = self._ctx.Process(
            target=self._target,
            args=(child, *self._args),
            name=f"scm-calib-pool-{slot.index}",
            daemon=True,
        )
        proc.start()
        child.close()
        slot.process, slot.conn, slot.ready, slot.key = proc, parent, False, None
        slot.started_at = time.monotonic()

    def ensure(self) -> int:
        """Start the processes of empty slots whose restart delay has passed; returns how
        many were started."""
        now = time.monotonic()
        started = 0
        for slot in self._slots:
            if slot.process is None and now >= slot.next_start:
                self._start(slot)
                started += 1
        return started

    def _bury(self, slot: _Slot) -> PoolEvent:
        proc = slot.process
        proc.join(timeout=1.0)
        event = PoolEvent(pid=proc.pid, key=slot.key, died=True, exitcode=proc.exitcode)
        now = time.monotonic()
        if now - slot.started_at > HEALTHY_AFTER_S:
            slot.backoff = RESTART_BACKOFF_S
        slot.next_start = now + slot.backoff
        slot.backoff = min(2.0 * slot.backoff, RESTART_BACKOFF_MAX_S)
        if slot.conn is not None:
            slot.conn.close()
        slot.process, slot.conn, slot.ready, slot.key = None, None, False, None
        self.restarts += 1
        if event.exitcode != -signal.SIGBUS:  # a storage fault, not a crash loop: the
            self._deaths.append(time.monotonic())  # database's check reports it
        self.last_death = f"process {event.pid}: {death_reason(event.exitcode)}" + (
            f" while running batch {event.key.astuple()}" if event.key else ""
        )
        return event

    # ---- work ----------------------------------------------------------------------------

    @property
    def idle(self) -> int:
        return sum(1 for s in self._slots if s.ready and s.key is None and s.alive)

    @property
    def busy_keys(self) -> set[BatchKey]:
        return {s.key for s in self._slots if s.key is not None}

    def submit(self, key: BatchKey) -> bool:
        """Send ``key`` to an idle, warmed-up process; False if there is none."""
        for slot in self._slots:
            if slot.ready and slot.key is None and slot.alive:
                try:
                    slot.conn.send(key.astuple())
                except OSError:
                    continue  # dying; wait() reports it
                slot.key = key
                return True
        return False

    def wait(self, timeout: float, extra: list[Any] | None = None) -> list[PoolEvent]:
        """Wait up to ``timeout`` s for a message, a process death or one of ``extra``
        (waitable objects, e.g. a wake-up socket); returns what happened to the pool."""
        handles: dict[Any, _Slot] = {}
        for slot in self._slots:
            if slot.process is not None:
                handles[slot.conn] = slot
                handles[slot.process.sentinel] = slot
        ready = wait([*handles, *(extra or [])], timeout=timeout)
        events: list[PoolEvent] = []
        dead: list[_Slot] = []
        for handle in ready:
            slot = handles.get(handle)
            if slot is None or slot.process is None or slot in dead:
                continue
            if handle is slot.conn:
                try:
                    while slot.conn.poll():
                        msg = slot.conn.recv()
                        if msg[0] == "ready":
                            slot.ready = True
                        elif msg[0] == "done":
                            events.append(
                                PoolEvent(slot.process.pid, BatchKey(*msg[1]), outcome=msg[2])
                            )
                            slot.key = None
                except (EOFError, OSError):
                    dead.append(slot)
            elif not slot.process.is_alive():
                dead.append(slot)
        for slot in dead:
            events.append(self._bury(slot))
        return events

    # ---- state ---------------------------------------------------------------------------

    def health(self) -> Health:
        """Complete when every process is up and warmed up (has said "ready")."""
        size = len(self._slots)
        up = sum(1 for s in self._slots if s.alive and s.ready)
        starting = sum(1 for s in self._slots if s.alive and not s.ready)
        busy = sum(1 for s in self._slots if s.key is not None)
        recent = sum(1 for t in self._deaths if time.monotonic() - t < HEALTHY_AFTER_S)
        if recent > 2 * size:
            ok, detail = (
                False,
                (
                    f"pool processes keep dying ({recent} in the last {HEALTHY_AFTER_S:.0f} s; "
                    f"last: {self.last_death})"
                ),
            )
        elif up < size:
            ok = False
            detail = (
                f"{up} of {size} pool processes up ({starting} starting, "
                f"{size - up - starting} being replaced)"
            )
        else:
            ok, detail = True, f"{up} pool processes, {busy} busy"
        return Health(ok, detail)

    def pids(self) -> list[int]:
        return [s.process.pid for s in self._slots if s.process is not None]

    def shutdown(self, timeout: float = 5.0) -> None:
        """Ask idle processes to exit, terminate busy ones (their batches' leases are taken
        back by the next server at its start, or expire)."""
        for slot in self._slots:
            if slot.process is None:
                continue
            if slot.key is None and slot.conn is not None:
                with contextlib.suppress(OSError):
                    slot.conn.send(None)
            else:
                slot.process.terminate()
        deadline = time.monotonic() + timeout
        for slot in self._slots:
            if slot.process is None:
                continue
            slot.process.join(timeout=max(0.0, deadline - time.monotonic()))
            if slot.process.is_alive():
                slot.process.terminate()
                slot.process.join(timeout=2.0)
            if slot.conn is not None:
                slot.conn.close()
            slot.process, slot.conn, slot.key, slot.ready = None, None, None, False
