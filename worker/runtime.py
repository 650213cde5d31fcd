"""Per-process runtime: the store, the study cache and a dispatcher, made on first use."""

from __future__ import annotations

import ctypes
import logging
import multiprocessing
import os
import signal
import sys
from dataclasses import dataclass, field
from functools import lru_cache

from services.config import Settings, get_settings
from services.store import Store
from services.store.records import BatchKey

from .orchestrator import ContextCache, Dispatcher, execute_batch


@dataclass
class Runtime:
    """What a worker process needs to run batches."""

    store: Store
    dispatcher: Dispatcher | None
    cache: ContextCache = field(default_factory=ContextCache)

    def execute(self, key: BatchKey) -> str:
        return execute_batch(self.store, key, self.cache, self.dispatcher)


def celery_dispatcher(settings: Settings):
    from .celery_app import make_celery
    from .dispatch import CeleryDispatcher

    return CeleryDispatcher(make_celery(settings))


@lru_cache(maxsize=1)
def process_runtime() -> Runtime:
    """The runtime of a Celery worker process (settings from the environment)."""
    settings = get_settings()
    return Runtime(Store.from_settings(settings), celery_dispatcher(settings))


_local_runtimes: dict[str, Runtime] = {}


def _local_runtime(store_args: tuple[str, float, int]) -> Runtime:
    rt = _local_runtimes.get(store_args[0])
    if rt is None:
        url, lease, attempts = store_args
        rt = Runtime(Store.open(url, lease_seconds=lease, max_attempts=attempts), None)
        _local_runtimes[url] = rt
    return rt


def _exit_with_parent() -> None:
    """Linux: have the kernel send SIGTERM to this process when its parent (the server) dies,
    even by SIGKILL, so that no orphaned pool process is left behind (elsewhere: no-op)."""
    parent = multiprocessing.parent_process()
    if not sys.platform.startswith("linux") or parent is None:
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    # the server died before prctl took effect (compare pids: the server may itself be pid 1,
    # as in the Docker image)
    if os.getppid() != parent.pid:
        os._exit(0)


def init_local_process(store_args: tuple[str, float, int]) -> None:
    """Initializer of the embedded pool's processes: exit with the server, open the store and
    load the compiled simulator before the first batch arrives (failures surface again in the
    batch)."""
    from scm_core.simulator import warm_up

    _exit_with_parent()
    try:
        _local_runtime(store_args)
        warm_up()
    except Exception:
        logging.getLogger(__name__).exception("local worker process start-up failed")


def run_local_batch(store_args: tuple[str, float, int], key: tuple[int, int, int]) -> str:
    """Entry point of the embedded pool's processes: run one batch (no dispatcher: the
    parent's loop dispatches the next stage). store_args: (url, lease_seconds, max_attempts)."""
    return _local_runtime(store_args).execute(BatchKey(*key))
