"""Per-process runtime: the store, the study cache and a dispatcher, made on first use."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
from dataclasses import dataclass, field
from functools import lru_cache

from services.config import Settings, get_settings
from services.lifetime import exit_with_parent
from services.store import Store
from services.store.records import BatchKey

from .orchestrator import ContextCache, Dispatcher, execute_batch

#: niceness added to an embedded pool process: a study's batches take the cores the server's
#: own work leaves (pages, and the figures a stage's end has drawn), not the other way round;
#: alone on the machine they get all of it, and the results do not depend on it
POOL_NICENESS = 10


@dataclass
class Runtime:
    """What a worker process needs to run batches."""

    store: Store
    dispatcher: Dispatcher | None
    cache: ContextCache = field(default_factory=ContextCache)

    def execute(self, key: BatchKey, worker: str | None = None) -> str:
        return execute_batch(self.store, key, self.cache, self.dispatcher, worker)


def celery_dispatcher(settings: Settings):
    from .celery_app import make_celery
    from .dispatch import CeleryDispatcher

    return CeleryDispatcher(make_celery(settings))


@lru_cache(maxsize=1)
def process_runtime() -> Runtime:
    """The runtime of a Celery worker process (settings from the environment)."""
    settings = get_settings()
    return Runtime(Store.from_settings(settings), celery_dispatcher(settings))


def local_worker_id(owner: str) -> str:
    """The lease holder name of an embedded pool process: ``<owner>/<pid>``, where ``owner``
    (``local/<host>/<server instance>``) names the server that started it."""
    return f"{owner}/{os.getpid()}"


def pool_process_main(conn, store_args: tuple[str, float, int], owner: str) -> None:
    """Main of an embedded pool process (:class:`worker.local_pool.SupervisedPool`): exit
    with the server, open the store, load the compiled simulator, say "ready", then run each
    batch key received on ``conn`` and answer its outcome. One numba thread: the pool's
    processes already use the cores; niced by :data:`POOL_NICENESS`. store_args: (url,
    lease_seconds, max_attempts)."""
    exit_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the server's; it stops us
    import numba

    from scm_core.simulator import warm_up

    numba.set_num_threads(1)
    with contextlib.suppress(OSError):  # batches yield the cores to serving (pages, figures)
        os.nice(POOL_NICENESS)
    url, lease, attempts = store_args
    me = local_worker_id(owner)
    try:
        runtime = Runtime(Store.open(url, lease_seconds=lease, max_attempts=attempts), None)
        warm_up()
    except Exception:
        logging.getLogger(__name__).exception("pool process %s failed to start", me)
        raise SystemExit(3) from None
    conn.send(("ready", os.getpid()))
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            break
        if msg is None:
            break
        key = BatchKey(*msg)
        try:
            outcome = runtime.execute(key, me)
        except Exception as exc:  # execute_batch logged it and released the lease
            text = " ".join(str(exc).split())[:300]
            outcome = f"error: {type(exc).__name__}: {text}"
        conn.send(("done", key.astuple(), outcome))
    runtime.store.close()
