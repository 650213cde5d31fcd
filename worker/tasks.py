"""Celery tasks: run one work batch. State lives in the database (see orchestrator)."""

from __future__ import annotations

import logging

from celery import shared_task
from celery.signals import worker_process_init

from services.store.records import BatchKey

from .runtime import process_runtime

log = logging.getLogger(__name__)


@shared_task(name="scm_calib.run_batch", bind=True, max_retries=None)
def run_batch(self, study_id: int, stage_index: int, batch_index: int) -> str:
    """Claim and run one batch; a duplicate or stale delivery is skipped by the store."""
    rt = process_runtime()
    key = BatchKey(study_id, stage_index, batch_index)
    try:
        return rt.execute(key)
    except Exception as exc:  # released in the store (attempt counted); the reaper re-dispatches
        log.warning("batch %s failed: %s", key, exc)
        return "failed"


@worker_process_init.connect
def warm_up_process(**_: object) -> None:
    """In every pool process at start (prefork children; the solo pool's own process): open
    the store (a database at the wrong schema revision is reported now, not at the first
    task) and load the compiled simulator, so the first batch starts at once."""
    from scm_core.simulator import warm_up

    try:
        process_runtime()
        log.info("simulator ready in %.2f s", warm_up())
    except Exception:  # tasks report it again; the worker stays up for the next attempt
        log.exception("worker process start-up failed")
