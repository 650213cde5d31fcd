"""Morris sensitivity studies over HTTP, embedded: the app's local process pool (2 processes)
runs the design points as work batches; the statistics served are bit-identical to
``run_sensitivity`` in this process on the same dataset, the design points and their F, T, z
are the samples of stage 0, and calibration-only endpoints refuse a sensitivity study."""

from __future__ import annotations

import csv
import io
import json
import time

import numpy as np
import pytest
from test_api_support import AUTH, TOKEN, api_client, fresh_database, upload_file

from scm_core.calibration import CaseDefinition, MorrisSettings, run_sensitivity
from scm_core.signals.responses import N_RESPONSES, RESPONSE_KEYS
from services.client import SCMCalibClient
from services.store import Store
from services.studies import work_batches
from services.studies.datasets import load_datasets

# tests share one server (module fixture) and read what earlier ones stored: one xdist worker
pytestmark = pytest.mark.xdist_group("test_api_sensitivity")

TIMEOUT = 300.0
CASE = {
    "name": "screen",
    "parameters": {"phi": {"dist": "uniform", "lower": 20.0, "upper": 35.0}},
    "nominal": {"sigma_F": 5.0, "sigma_T": 0.5, "sigma_z": 0.001},
    "simulator": {
        "duration": 8.0,
        "dx": 0.01,
        "dt": 0.04,
        "offset_F": 3.0,
        "offset_T": 3.0,
        "offset_z": 3.0,
    },
}
DESIGN = {"r": 4, "levels": 4, "seed": 21, "batch_size": 6, "bounds": {"c": [0.0, 500.0]}}


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory):
    """(client, url, study id, dataset id, bodies seen while it ran)."""
    directory = tmp_path_factory.mktemp("sensitivity")
    with (
        fresh_database("sqlite", directory) as url,
        api_client(url, start_local_runtime=True, worker_concurrency=2) as client,
    ):
        up = upload_file(client)
        assert up.status_code == 201, up.text
        dataset_id = up.json()["id"]
        r = client.post(
            "/sensitivity", json={"case": CASE, "dataset_id": dataset_id, **DESIGN}, headers=AUTH
        )
        assert r.status_code == 201, r.text
        study_id = r.json()["id"]
        assert r.headers["location"] == f"/sensitivity/{study_id}"
        seen = [r.json()]
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            body = client.get(f"/sensitivity/{study_id}").json()
            seen.append(body)
            if body["status"] not in ("queued", "running"):
                break
            time.sleep(0.3)
        yield client, url, study_id, dataset_id, seen


def _reference(url: str, dataset_id: int):
    case = CaseDefinition.from_dict(CASE)
    store = Store.open(url)
    try:
        dataset = load_datasets(store, case, [dataset_id])[0]
    finally:
        store.close()
    bounds = {k: tuple(v) for k, v in DESIGN["bounds"].items()}
    return run_sensitivity(dataset, case, MorrisSettings(r=4, levels=4, seed=21, bounds=bounds))


def test_statistics_are_those_of_run_sensitivity(finished) -> None:
    client, url, study_id, dataset_id, seen = finished
    body = client.get(f"/sensitivity/{study_id}").json()
    assert body["status"] == "completed", body
    ref = _reference(url, dataset_id)
    assert body["result"] == json.loads(json.dumps(ref.to_dict()))
    assert body["n_points"] == ref.n_runs == 4 * 7
    assert [f["name"] for f in body["factors"]] == ["k_star", "n", "c", "phi", "D_soil", "J"]
    c = body["factors"][2]
    assert (c["lower"], c["upper"], c["log_scale"], c["unit"]) == (0.0, 500.0, False, "Pa")
    assert body["factors"][0]["log_scale"] is True
    assert body["dataset_id"] == dataset_id and body["joint_k"] is True

    p = body["progress"]
    assert p["evaluations_done"] == p["evaluations_planned"] == 28
    assert p["batches_done"] == p["batches_total"] == len(work_batches(28, 6))
    assert p["eta_seconds"] == 0.0
    assert p["model_runs"] == 28 and p["exponent"] is None
    assert all(s["progress"]["evaluations_planned"] == 28 for s in seen)


def test_design_points_are_the_stage_samples(finished) -> None:
    client, url, study_id, dataset_id, _ = finished
    ref = _reference(url, dataset_id)
    page = client.get(f"/studies/{study_id}/stages/0/samples", params={"limit": 100}).json()
    assert page["names"] == ["k_star", "n", "c", "phi", "D_soil", "J"]
    assert page["total"] == 28
    assert np.array_equal(np.array(page["samples"], dtype=float), ref.points)
    r = client.get(f"/studies/{study_id}/stages/-1/samples.csv")
    rows = list(csv.reader(io.StringIO(r.text)))
    assert rows[0][:7] == ["sample", "k_star", "n", "c", "phi", "D_soil", "J"]
    assert rows[0][-N_RESPONSES:] == [f"{r}[wf34_s020]" for r in RESPONSE_KEYS]
    Y = np.array([[float(v) for v in row[-N_RESPONSES:]] for row in rows[1:]])
    assert np.array_equal(Y, ref.outputs, equal_nan=True)


def test_listing_and_calibration_endpoints(finished) -> None:
    client, _, study_id, _, _ = finished
    listing = client.get("/sensitivity").json()
    assert [s["id"] for s in listing["items"]] == [study_id] and listing["total"] == 1
    assert client.get("/studies", params={"kind": "sensitivity"}).json()["total"] == 1
    assert client.get("/studies", params={"kind": "calibration"}).json()["total"] == 0
    brief = client.get("/studies").json()["items"][0]
    assert brief["kind"] == "sensitivity" and brief["id"] == study_id

    r = client.get(f"/studies/{study_id}/summary")
    assert r.status_code == 409 and f"/sensitivity/{study_id}" in r.json()["detail"]
    r = client.post("/pooled", json={"study_ids": [study_id]})
    assert r.status_code == 422 and "not a calibration" in r.json()["detail"]
    r = client.post(f"/studies/{study_id}/cancel", headers=AUTH)
    assert r.status_code == 409  # it has ended
    # its dashboard page: design points and a table of its runs, no tempering columns
    live = client.get(f"/ui/f/studies/{study_id}/live").text
    assert "design points (model runs)" in live and "samples per stage" not in live
    assert "exponent p" not in live and "<h2>Runs</h2>" in live


def test_python_client(finished) -> None:
    client, _, study_id, dataset_id, _ = finished
    api = SCMCalibClient("http://testserver", token=TOKEN, http_client=client)
    body = api.sensitivity(study_id)
    assert body["result"]["method"] == "morris"
    assert api.studies(kind="sensitivity")["total"] == 1
    new = api.create_sensitivity(
        dataset_id, case=CASE, r=2, separate_k=True, bounds={"k_c": (-1e5, 1e5)}, seed=3
    )
    assert new["joint_k"] is False and new["n_points"] == 2 * 8
    assert new["factors"][0] == {
        "name": "k_c", "lower": -1e5, "upper": 1e5, "log_scale": False, "unit": "N/m^(n+1)"
    }  # fmt: skip
    assert api.cancel(new["id"])["status"] == "cancelled"
