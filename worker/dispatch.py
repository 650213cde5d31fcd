"""Where work batches go in the distributed mode: Celery (the embedded mode's local pool is
:class:`worker.local.LocalRuntime`)."""

from __future__ import annotations

import logging
from collections.abc import Sequence

from services.store.records import BatchKey

log = logging.getLogger(__name__)


class CeleryDispatcher:
    """Sends one ``scm_calib.run_batch`` task per batch to the broker."""

    def __init__(self, app) -> None:
        self.app = app

    def dispatch(self, keys: Sequence[BatchKey]) -> None:
        for k in keys:
            self.app.send_task(
                "scm_calib.run_batch", args=(k.study_id, k.stage_index, k.batch_index)
            )
