"""The service over HTTP: ``scm-calib serve`` with Celery workers (distributed), and the embedded
server killed and restarted in the middle of a study. Final samples are compared bit for bit with
``scm-calib calibrate`` on the same case (fixture ``reference_samples``)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import httpx
import numpy as np
import pytest
from svc_support import (
    CASE_FILE,
    LEASE_SECONDS,
    LOG_FILE,
    LOG_FILE2,
    PREDICTION,
    ROOT,
    free_port,
    service_env,
)

from scm_core.calibration import MorrisSettings, load_case, run_sensitivity
from scm_core.signals import load_log
from services.client import SCMCalibClient
from services.config import new_token

TIMEOUT = 600.0


def _serve(processes, env, port, name="api", extra=()):
    proc = processes.start(
        name, ["serve", "--port", str(port), "--log-level", "warning", *extra], env
    )
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"serve exited early:\n{processes.logs()}")
        try:
            if httpx.get(f"{url}/health", timeout=1.0).status_code == 200:
                return proc, url
        except httpx.HTTPError:
            time.sleep(0.2)
    pytest.fail("serve did not come up")


def _final_samples(client: SCMCalibClient, study_id: int) -> np.ndarray:
    s = client.samples(study_id)
    return np.ascontiguousarray(s.samples, dtype=np.float64)


@pytest.mark.slow
def test_api_and_two_celery_workers(
    pg_url, redis_server, processes, reference_samples, reference_update, reference_prediction
):
    """A calibration, a sensitivity study, an update of the calibration with the slip 0.5 log
    and a prediction from it, all through the API on two Celery workers: bit-identical to
    ``calibrate``, ``run_sensitivity``, ``calibrate --update-of`` and ``predict``."""
    token, digest = new_token()
    env = service_env(pg_url, redis_server.url)
    env["SCM_CALIB_API_TOKENS"] = digest
    processes.worker(env, "worker0")
    processes.worker(env, "worker1")
    processes.reaper(env)
    _, url = _serve(processes, env, free_port())
    with SCMCalibClient(url, token=token) as client:
        assert client.ready()["status"] == "ready"
        ds = client.upload_log(LOG_FILE)
        again = client.upload_log(LOG_FILE)
        assert again["id"] == ds["id"] and again["created"] is False
        study = client.create_study(case=CASE_FILE, dataset_ids=[ds["id"]])
        final = client.wait(study["id"], timeout=TIMEOUT, poll=0.5)
        assert final["status"] == "completed", (final, processes.logs())
        got = _final_samples(client, study["id"])
        # the case screens proposals with a surrogate (delayed acceptance): it was really used
        stages = client.stages(study["id"])
        assert sum(st["first_stage_rejections"] or 0 for st in stages) > 0

        # a Morris sensitivity study on the same workers (its design points as work batches)
        sens = client.create_sensitivity(ds["id"], case=CASE_FILE, r=3, seed=4, batch_size=4)
        assert client.wait(sens["id"], timeout=TIMEOUT, poll=0.5)["status"] == "completed"
        result = client.sensitivity(sens["id"])["result"]
        events = client.events(sens["id"], limit=1000)
        workers = {e["payload"]["worker"] for e in events if e["kind"] == "batch_done"}

        # the posterior updated with a new log, and predictions of that log's test
        ds2 = client.upload_log(LOG_FILE2)
        update = client.create_study(update_of=study["id"], dataset_ids=[ds2["id"]])
        pred = client.submit(
            "predictions", study_id=study["id"], dataset_ids=[ds2["id"]], batch_size=5, **PREDICTION
        )
        assert client.wait(update["id"], timeout=TIMEOUT, poll=0.5)["status"] == "completed"
        updated = client.get_study(update["id"])
        got_update = _final_samples(client, update["id"])
        # its stage 0 ran the new log only (the old one's responses are the parent's), once
        # per distinct point of the parent's population
        update_stage0 = client.stages(update["id"])[0]
        assert client.wait(pred["id"], timeout=TIMEOUT, poll=0.5)["status"] == "completed"
        predicted = client.read("predictions", pred["id"])["result"]
    assert got.tobytes() == reference_samples.samples.tobytes()
    assert got_update.tobytes() == reference_update.samples.tobytes()
    assert updated["result"]["log_evidence_increment"] == updated["log_evidence"]
    distinct = len(np.unique(reference_samples.samples, axis=0))
    assert update_stage0["part_runs"] == update_stage0["model_runs"] == distinct
    assert predicted["predictions"] == reference_prediction["datasets"]
    case = load_case(CASE_FILE)
    meta = json.loads(LOG_FILE.with_suffix(".json").read_text())
    dataset = load_log(LOG_FILE.read_bytes(), metadata=meta, offset=case.data.offset)
    ref = run_sensitivity(dataset, case, MorrisSettings(r=3, seed=4))
    assert result == json.loads(json.dumps(ref.to_dict()))  # bit-identical to one process
    assert len({w.split(":")[1] for w in workers}) == 2  # both Celery workers ran points


@pytest.mark.slow
def test_embedded_server_killed_and_restarted(tmp_path, processes, reference_samples):
    token, digest = new_token()
    env = dict(os.environ)
    env.update(
        SCM_CALIB_DATA_DIR=str(tmp_path / "data"),
        SCM_CALIB_API_TOKENS=digest,
        SCM_CALIB_LEASE_SECONDS=str(LEASE_SECONDS),
        SCM_CALIB_MAX_ATTEMPTS="5",
        NUMBA_NUM_THREADS="1",
    )
    env.pop("SCM_CALIB_BROKER_URL", None)
    env.pop("SCM_CALIB_DATABASE_URL", None)
    port = free_port()
    # own session: SIGKILL the server together with its local pool
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "services.cli",
            "serve",
            "--port",
            str(port),
            "--workers",
            "2",
            "--log-level",
            "warning",
        ],
        env=env,
        cwd=ROOT,
        stdout=open(tmp_path / "serve1.log", "w"),  # noqa: SIM115
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    processes.procs.append(server)
    url = f"http://127.0.0.1:{port}"
    with SCMCalibClient(url, token=token, timeout=30) as client:
        deadline = time.monotonic() + 60
        while True:
            try:
                client.health()
                break
            except Exception:
                if time.monotonic() > deadline:
                    pytest.fail((tmp_path / "serve1.log").read_text())
                time.sleep(0.2)
        ds = client.upload_log(LOG_FILE)
        study = client.create_study(case=CASE_FILE, dataset_ids=[ds["id"]])
        deadline = time.monotonic() + 300
        while (client.get_study(study["id"]).get("current_stage") or 0) < 1:
            assert time.monotonic() < deadline, "study did not reach stage 1"
            time.sleep(0.1)
    os.killpg(server.pid, signal.SIGKILL)  # API, local pool and its running batches
    server.wait()
    _, url2 = _serve(processes, env, port, name="serve2", extra=("--workers", "2"))
    with SCMCalibClient(url2, token=token) as client:
        final = client.wait(study["id"], timeout=TIMEOUT, poll=0.5)
        assert final["status"] == "completed", (final, processes.logs())
        got = _final_samples(client, study["id"])
    assert got.tobytes() == reference_samples.samples.tobytes()
