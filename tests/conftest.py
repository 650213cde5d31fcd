"""Test-session setup shared by every test package."""

import contextlib
import os
import signal

import pytest

from scm_core.simulator import warm_up
from scm_core.simulator.jit_cache import ensure_fresh_cache


@contextlib.contextmanager
def _file_lock(path):
    """An exclusive lock on ``path`` across processes (POSIX; elsewhere no lock)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def pytest_configure(config: pytest.Config) -> None:
    """Ctrl-C as in a terminal: a shell's background job (``pytest &`` in a script) starts with
    SIGINT ignored, and every process it starts inherits that, so the Ctrl-C tests' commands
    would never see their SIGINT. Python's own handler is put back (the child processes then
    start with the default disposition); a run in a terminal already has it."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        with contextlib.suppress(ValueError):  # not the main thread: nothing to put back
            signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session", autouse=True)
def _fresh_simulator_cache(tmp_path_factory):
    """Tests that call jitted simulator functions directly (not through the entry points,
    which check it themselves) load no cached code built from other sources. Under
    pytest-xdist the workers take turns: the first compiles the simulator into numba's disk
    cache (about 20 s on a fresh clone), the others then load it instead of each compiling
    it again on the same cores."""
    if "PYTEST_XDIST_WORKER" not in os.environ:
        ensure_fresh_cache()
        return
    with _file_lock(tmp_path_factory.getbasetemp().parent / "simulator-compile.lock"):
        ensure_fresh_cache()
        warm_up()
