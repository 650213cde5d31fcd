"""The embedded pool's processes live with the server and die with it: a pool process runs
work while its parent lives, and exits when the parent is SIGKILLed (no orphans)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

SCRIPT = textwrap.dedent(
    """
    import os, sys, time
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context
    from worker.runtime import _exit_with_parent

    if __name__ == "__main__":
        ex = ProcessPoolExecutor(1, mp_context=get_context("spawn"), initializer=_exit_with_parent)
        pid, ppid = ex.submit(os.getpid).result(), ex.submit(os.getppid).result()
        print(pid, ppid == os.getpid(), flush=True)
        time.sleep(60)
    """
)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_pool_process_works_and_exits_with_its_parent(tmp_path) -> None:
    script = tmp_path / "parent.py"
    script.write_text(SCRIPT)
    proc = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=os.getcwd()
    )
    try:
        line = proc.stdout.readline().split()
        child, same_parent = int(line[0]), line[1] == "True"
        assert same_parent  # the child ran work with its parent alive
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
