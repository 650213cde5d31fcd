"""Celery tasks: run one work batch. State lives in the database (see orchestrator)."""

from __future__ import annotations

import logging

from celery import shared_task

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
