"""Distributed mode against the real servers: PostgreSQL, Redis and Celery worker processes.

Each test runs the reduced study of ``data/svc_case.toml`` and compares its final samples, bit for
bit, with ``scm-calib calibrate`` on the same case (fixture ``reference_samples``). Faults: a worker
killed with SIGKILL in the middle of a batch, the broker restarted (queued messages lost), and
every batch delivered twice.
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
from svc_support import LEASE_SECONDS, add_example_dataset, service_env

from services.config import Settings
from services.store import Store
from services.studies import calibration_spec, create_and_start
from worker.celery_app import make_celery
from worker.dispatch import CeleryDispatcher
from worker.orchestrator import wait_for_study

TIMEOUT = 600.0  # s; the undisturbed study takes ~30-60 s on two cores


def _setup(pg_url, redis_url, processes, n_workers=2, reaper=True):
    env = service_env(pg_url, redis_url)
    workers = [processes.worker(env, f"worker{i}") for i in range(n_workers)]
    if reaper:
        processes.reaper(env)
    store = Store.open(pg_url, lease_seconds=LEASE_SECONDS, max_attempts=5)
    settings = Settings(database_url=pg_url, broker_url=redis_url)
    return store, CeleryDispatcher(make_celery(settings)), workers


def _final_samples(store: Store, study_id: int) -> np.ndarray:
    last = store.stages.list(study_id)[-1]
    return store.samples.arrays(study_id, last.stage_index).samples


def _assert_same_as_reference(store, study_id, reference, processes):
    final = wait_for_study(store, study_id, TIMEOUT)
    assert final.status == "completed", (final.status, final.error, processes.logs())
    samples = _final_samples(store, study_id)
    assert samples.tobytes() == reference.samples.tobytes()
    return final


def _wait_for_lease(store, study_id, stage_min=1, timeout=120.0):
    """The first batch leased at stage >= stage_min: (batch record)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        study = store.studies.get(study_id)
        if study.current_stage is not None and study.current_stage >= stage_min:
            leased = [
                b for b in store.batches.list(study_id, study.current_stage) if b.status == "leased"
            ]
            if leased:
                return leased[0]
        time.sleep(0.05)
    pytest.fail("no batch was leased in time")


def _submit(store, case, dataset_id, dispatcher):
    spec = calibration_spec(store, Settings(), case, [dataset_id])
    return store.studies.get(create_and_start(store, spec, dispatcher))


def test_two_workers_match_calibrate_and_double_delivery_counts_once(
    pg_url, redis_server, processes, svc_case, reference_samples
):
    store, dispatcher, _ = _setup(pg_url, redis_server.url, processes)
    ds = add_example_dataset(store, svc_case)
    study = _submit(store, svc_case, ds, dispatcher)
    # every batch of stage 0 is delivered a second time
    dispatcher.dispatch([b.key for b in store.batches.list(study.id, 0)])
    final = _assert_same_as_reference(store, study.id, reference_samples, processes)
    kinds = [e.kind for e in store.events.list(study.id, limit=10_000)]
    assert kinds.count("stage_done") == len(store.stages.list(study.id))
    # each batch's result was stored once: model runs match the in-process run
    assert final.model_runs == sum(s.model_runs for s in store.stages.list(study.id))


@pytest.mark.slow
def test_worker_killed_mid_batch(pg_url, redis_server, processes, svc_case, reference_samples):
    store, dispatcher, workers = _setup(pg_url, redis_server.url, processes)
    ds = add_example_dataset(store, svc_case)
    study = _submit(store, svc_case, ds, dispatcher)
    batch = _wait_for_lease(store, study.id, stage_min=1)
    pid = int(batch.worker_id.split(":")[1])
    victim = next(w for w in workers if w.pid == pid)
    os.kill(victim.pid, signal.SIGKILL)
    victim.wait()
    _assert_same_as_reference(store, study.id, reference_samples, processes)
    kinds = [e.kind for e in store.events.list(study.id, limit=10_000)]
    assert "lease_expired" in kinds  # the reaper took the dead worker's batch back


@pytest.mark.slow
def test_broker_restart_mid_stage(pg_url, redis_server, processes, svc_case, reference_samples):
    store, dispatcher, _ = _setup(pg_url, redis_server.url, processes)
    ds = add_example_dataset(store, svc_case)
    study = _submit(store, svc_case, ds, dispatcher)
    _wait_for_lease(store, study.id, stage_min=1)
    redis_server.stop()  # queued messages are gone with it (no persistence)
    time.sleep(2.0)
    redis_server.start()
    _assert_same_as_reference(store, study.id, reference_samples, processes)
