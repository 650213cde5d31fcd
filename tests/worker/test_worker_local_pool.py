"""The embedded server's supervised pool (:class:`worker.local_pool.SupervisedPool`) with a
trivial process main: work is answered, a process killed in the middle of a batch is reported
with that batch and replaced while the other keeps working, and pool processes die with the
server even when the thread that asked for work has long ended."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from services.store import BatchKey
from worker.local_pool import SupervisedPool
from worker.runtime import exit_with_parent

SLOW = 99  # batch index the echo main sleeps on (to be killed in the middle of it)


def echo_main(conn) -> None:
    """A pool process main: "ready", then "done" with the pid for each key."""
    exit_with_parent()
    conn.send(("ready", os.getpid()))
    while True:
        msg = conn.recv()
        if msg is None:
            return
        if msg[2] == SLOW:
            time.sleep(60)
        conn.send(("done", msg, f"pid {os.getpid()}"))


def _run_until(pool: SupervisedPool, predicate, timeout: float = 30.0) -> list:
    events: list = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        pool.ensure()
        events += pool.wait(0.2)
        if predicate(events):
            return events
    pytest.fail(f"pool did not get there in {timeout} s: {events}")


def test_work_death_and_replacement() -> None:
    pool = SupervisedPool(2, echo_main, ())
    try:
        _run_until(pool, lambda ev: pool.idle == 2)
        a, b = BatchKey(1, 0, 0), BatchKey(1, 0, SLOW)
        assert pool.submit(a) and pool.submit(b)
        assert not pool.submit(BatchKey(1, 0, 2))  # both busy
        events = _run_until(pool, lambda ev: any(e.key == a for e in ev))
        assert events[0].outcome.startswith("pid ") and not events[0].died
        victim = next(s.process.pid for s in pool._slots if s.key == b)
        survivor = next(p for p in pool.pids() if p != victim)
        os.kill(victim, signal.SIGKILL)
        events = _run_until(pool, lambda ev: any(e.died for e in ev))
        died = next(e for e in events if e.died)
        assert died.pid == victim and died.key == b and died.exitcode == -signal.SIGKILL
        assert not pool.health().ok and "1 being replaced" in pool.health().detail
        _run_until(pool, lambda ev: pool.idle == 2)  # replaced after the back-off
        assert survivor in pool.pids() and victim not in pool.pids()
        assert pool.health().ok and pool.restarts == 1
        assert pool.submit(BatchKey(1, 0, 3))
        _run_until(pool, lambda ev: any(e.key == BatchKey(1, 0, 3) for e in ev))
    finally:
        pool.shutdown()
    assert pool.pids() == []


SCRIPT = textwrap.dedent(
    """
    import sys, threading, time
    sys.path.insert(0, {here!r})
    from test_worker_local_pool import echo_main
    from services.store import BatchKey
    from worker.local_pool import SupervisedPool

    def owner():  # the long-lived thread that owns the pool
        pool = SupervisedPool(1, echo_main, ())
        while pool.idle < 1:
            pool.ensure(); pool.wait(0.2)
        print(pool.pids()[0], flush=True)
        while True:
            pool.wait(1.0)

    if __name__ == "__main__":
        threading.Thread(target=owner, daemon=True).start()
        # short-lived threads come and go, as request threads do
        for _ in range(3):
            t = threading.Thread(target=time.sleep, args=(0.1,)); t.start(); t.join()
        time.sleep(60)
    """
)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_pool_process_exits_with_its_parent(tmp_path) -> None:
    script = tmp_path / "parent.py"
    here = os.path.dirname(os.path.abspath(__file__))
    script.write_text(SCRIPT.format(here=here))
    proc = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=os.getcwd()
    )
    try:
        child = int(proc.stdout.readline())
        time.sleep(0.5)
        os.kill(child, 0)  # alive while the parent lives, short-lived threads gone
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            try:
                os.kill(child, 0)
            except ProcessLookupError:
                return  # gone with its parent
            with open(f"/proc/{child}/stat") as f:
                if f.read().split()[2] == "Z":  # exited, not yet reaped by init
                    return
            time.sleep(0.1)
        pytest.fail(f"pool process {child} outlived its SIGKILLed parent")
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_death_is_told_in_words() -> None:
    """Issue 73: the pool's log line says which signal killed a process, and what a SIGBUS
    means here (a mapped page of the database's files could not be written)."""
    from worker.local_pool import death_reason

    assert death_reason(-signal.SIGKILL) == "killed by SIGKILL"
    bus = death_reason(-signal.SIGBUS)
    assert bus.startswith("killed by SIGBUS: a mapped page of the database's files")
    assert "storage" in bus and "\n" not in bus
    assert death_reason(3) == "exit code 3"
