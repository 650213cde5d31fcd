"""Predictions over HTTP, embedded (kind "prediction", a collection the kind brings itself):
the app's local process pool (2 processes) simulates the posterior draws as work batches; the
bands served are those of ``scm_core.calibration.predict`` (the core of ``scm-calib predict``)
in this process, bit for bit; bad requests answer 422 naming the field and store nothing; the
collection shows only its kind."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_api_support import (
    AUTH,
    LOG2,
    api_client,
    detail,
    fresh_database,
    row_counts,
    tiny_case,
    upload_file,
    wait_ended,
)

from scm_core.calibration import CaseDefinition, DatasetTerms
from scm_core.calibration.predict import predict
from scm_core.inference.posterior import pool_samples
from scm_core.signals.responses import N_RESPONSES
from services.store import Store
from services.studies.datasets import load_datasets

# tests share one server (module fixture) and read what earlier ones stored: one xdist worker
pytestmark = pytest.mark.xdist_group("test_api_predictions")

TIMEOUT = 300.0
CONDITIONS = [
    {"name": "slip 0.3", "W": 100.0, "slip": 0.3, "R": 0.125, "b": 0.15},
    {"W": 100.0, "carriage_speed": 0.01, "rim_speed": 0.005, "R": 0.125, "b": 0.15},
]


def _wait(client, study_id: int) -> dict:
    return wait_ended(client.get, f"/studies/{study_id}", TIMEOUT)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory):
    """(client, url, calibration id, dataset ids [slip 0.2, slip 0.5]) with the calibration
    completed on the slip 0.2 log."""
    directory = tmp_path_factory.mktemp("predictions")
    with (
        fresh_database("sqlite", directory) as url,
        api_client(url, start_local_runtime=True, worker_concurrency=2) as client,
    ):
        ids = [upload_file(client).json()["id"], upload_file(client, LOG2).json()["id"]]
        r = client.post(
            "/studies",
            json={"case": tiny_case(params=("phi",)), "dataset_ids": ids[:1]},
            headers=AUTH,
        )
        assert r.status_code == 201, r.text
        assert _wait(client, r.json()["id"])["status"] == "completed"
        yield client, url, r.json()["id"], ids


def _posterior(client, study_id: int) -> np.ndarray:
    stage = client.get(f"/studies/{study_id}").json()["current_stage"]
    page = client.get(f"/studies/{study_id}/stages/{stage}/samples?limit=500").json()
    return np.asarray(page["samples"], dtype=float)


def _expected(url: str, study_id: int, posterior, targets, draws, seed, roles):
    store = Store.open(url)
    try:
        case = CaseDefinition.from_dict(store.studies.get(study_id).case)
        if targets and isinstance(targets[0], int):
            targets = load_datasets(store, case, targets)
    finally:
        store.close()
    preds = predict(case, posterior, targets, draws=draws, seed=seed, roles=roles)
    return json.loads(json.dumps([p.to_dict() for p in preds]))


def test_prediction_of_datasets_is_the_core_predict_bit_for_bit(calibrated) -> None:
    client, url, study_id, ids = calibrated
    body = {"study_id": study_id, "dataset_ids": ids, "draws": 13, "seed": 4, "batch_size": 4}
    r = client.post("/predictions", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    pid = r.json()["id"]
    assert r.headers["location"] == f"/predictions/{pid}"
    assert r.json()["kind"] == "prediction" and r.json()["payload"]["study_id"] == study_id
    assert _wait(client, pid)["status"] == "completed"
    got = client.get(f"/predictions/{pid}").json()
    result = got["result"]
    assert result["draws"] == 13 and result["seed"] == 4 and result["level"] == 0.95
    posterior = _posterior(client, study_id)
    expected = _expected(url, study_id, posterior, ids, 13, 4, ["calibration", "predicted"])
    assert result["predictions"] == expected
    # the draws are the stage's samples, with their simulated F, T, z, Fy per dataset
    stage = client.get(f"/studies/{pid}/stages/0/samples?limit=100").json()
    assert len(stage["samples"]) == 13 and len(stage["responses"][0]) == 2 * N_RESPONSES
    for p in result["predictions"]:
        for band in p["responses"].values():
            sim = band["simulated"]
            assert sim["lo"] <= sim["median"] <= sim["hi"]


def test_prediction_of_conditions(calibrated) -> None:
    client, url, study_id, _ = calibrated
    body = {"study_id": study_id, "conditions": CONDITIONS, "draws": 8, "seed": 1}
    r = client.post("/predictions", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    assert _wait(client, r.json()["id"])["status"] == "completed"
    result = client.get(f"/predictions/{r.json()['id']}").json()["result"]
    stored = client.get(f"/predictions/{r.json()['id']}").json()["payload"]["conditions"]
    terms = [
        DatasetTerms(c["name"], {k: v for k, v in c.items() if k != "name"}, (math.nan,) * 3)
        for c in stored
    ]
    posterior = _posterior(client, study_id)
    assert result["predictions"] == _expected(url, study_id, posterior, terms, 8, 1, None)
    names = [p["name"] for p in result["predictions"]]
    assert names == ["slip 0.3", "condition 1"]
    # the second condition was given as speeds: slip 0.5 in both conventions
    assert result["predictions"][1]["slip_symmetric"] == pytest.approx(-0.5)
    assert all(p["responses"]["F"]["measured"] is None for p in result["predictions"])


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"study_id": 999}, "study_id: no study with id 999"),
        ({"dataset_ids": None}, "give exactly one of dataset_ids and conditions"),
        ({"conditions": CONDITIONS}, "give exactly one of dataset_ids and conditions"),
        ({"dataset_ids": [12345]}, "dataset_ids: no dataset with id 12345"),
        ({"dataset_ids": None, "conditions": [{"W": 100.0}]}, "conditions.0"),
        ({"dataset_ids": None, "conditions": [{"W": -1, "slip": 0.2}]}, "conditions.0"),
        ({"draws": 10**9}, "draws"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_bad_prediction_requests_name_the_field(calibrated, change, needle) -> None:
    client, url, study_id, ids = calibrated
    body = {"study_id": study_id, "dataset_ids": ids[1:], "draws": 5, **change}
    before = row_counts(url)
    r = client.post("/predictions", json=body, headers=AUTH)
    assert r.status_code == 422, r.text
    assert needle in detail(r)
    assert row_counts(url) == before


def test_collection_shows_only_its_kind(calibrated) -> None:
    client, _, study_id, ids = calibrated
    # its own prediction: under xdist the module's fixture may be rebuilt between its tests
    body = {"study_id": study_id, "dataset_ids": ids, "draws": 5, "seed": 2}
    r = client.post("/predictions", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    assert _wait(client, r.json()["id"])["status"] == "completed"
    r = client.get(f"/predictions/{study_id}")
    assert r.status_code == 404 and "is a calibration study" in detail(r)
    page = client.get("/predictions").json()
    assert page["total"] >= 1 and all(p["kind"] == "prediction" for p in page["items"])
    assert client.get("/predictions?status=bogus").status_code == 422
    # a prediction is no calibration: it cannot be predicted from or updated
    pid = page["items"][0]["id"]
    r = client.post("/predictions", json={"study_id": pid, "dataset_ids": ids}, headers=AUTH)
    assert r.status_code == 422 and "not a calibration" in detail(r)
    # writes need the token
    assert client.post("/predictions", json={"study_id": study_id}).status_code == 401


def test_a_run_groups_pooled_posterior_is_predicted(calibrated) -> None:
    """``pooled_with``: the draws come from the runs' final populations pooled with equal
    weight (scm_core's pool_samples, the prediction's seed), as ``scm-calib predict`` on a run
    group's folder; runs of another calibration are refused in words, storing nothing."""
    client, url, _, ids = calibrated
    case = tiny_case(params=("phi",))
    r = client.post(
        "/studies", json={"case": case, "dataset_ids": ids[:1], "runs": 2}, headers=AUTH
    )
    assert r.status_code == 201, r.text
    runs = r.json()["runs"]
    for sid in runs:
        assert _wait(client, sid)["status"] == "completed"
    body = {"study_id": runs[0], "pooled_with": runs[1:], "dataset_ids": ids[1:], "draws": 9}
    r = client.post("/predictions", json={**body, "seed": 3}, headers=AUTH)
    assert r.status_code == 201, r.text
    assert _wait(client, r.json()["id"])["status"] == "completed"
    result = client.get(f"/predictions/{r.json()['id']}").json()["result"]
    assert result["study_id"] == runs[0] and result["pooled_with"] == runs[1:]
    pooled = pool_samples([_posterior(client, s) for s in runs], seed=3)
    assert result["predictions"] == _expected(url, runs[0], pooled, ids[1:], 9, 3, ["predicted"])
    # another calibration (other data) is no run of this one; nor is the study itself
    other = client.post(
        "/studies", json={"case": case, "dataset_ids": ids[1:]}, headers=AUTH
    ).json()["id"]
    assert _wait(client, other)["status"] == "completed"
    for pooled_with, needle in [
        ([other], f"pooled_with: studies {runs[0]} and {other} are calibrations of different"),
        ([runs[0]], "pooled_with: a study is listed twice"),
        ([999], "pooled_with: no study with id 999"),
    ]:
        before = row_counts(url)
        r = client.post("/predictions", json={**body, "pooled_with": pooled_with}, headers=AUTH)
        assert r.status_code == 422 and needle in detail(r), r.text
        assert row_counts(url) == before
