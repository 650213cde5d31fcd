"""The Celery application (Redis broker). Settings chosen for long CPU-bound tasks.

Work batches take minutes, so: a worker takes one message at a time (prefetch 1), acknowledges it
only after the task ran (late acks; a killed worker's message is redelivered), the hard time limit
stays below Redis' visibility timeout (otherwise a slow task would be redelivered while it still
runs), and no result backend: results go to the database.
"""

from __future__ import annotations

from celery import Celery

from services.config import Settings

TASK_TIME_LIMIT = 3 * 3600  # s, per work batch
VISIBILITY_TIMEOUT = TASK_TIME_LIMIT + 1800  # s, Redis redelivers unacked messages after this


def make_celery(settings: Settings) -> Celery:
    """A configured Celery app for ``settings.broker_url``."""
    app = Celery("scm_calib", broker=settings.broker_url, include=["worker.tasks"])
    app.conf.update(
        task_serializer="json",
        accept_content=["json"],
        task_acks_late=True,
        task_reject_on_worker_lost=True,
        worker_prefetch_multiplier=1,
        task_time_limit=TASK_TIME_LIMIT,
        task_soft_time_limit=TASK_TIME_LIMIT - 60,
        task_ignore_result=True,
        broker_transport_options={"visibility_timeout": VISIBILITY_TIMEOUT},
        broker_connection_retry_on_startup=True,
        broker_connection_max_retries=None,
        worker_concurrency=settings.worker_concurrency,
        worker_hijack_root_logger=False,
        task_default_queue="scm_calib",
    )
    return app
