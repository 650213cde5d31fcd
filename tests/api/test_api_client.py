"""The Python client over the app in process (FastAPI's TestClient as its httpx client)."""

from __future__ import annotations

import pytest
from test_api_support import EXAMPLES, TOKEN, api_client, fresh_database, summary_doc

from scm_core.calibration import load_case
from services.client import SCMCalibClient, SCMCalibError, SCMCalibTimeoutError
from services.studies import work_batches


@pytest.fixture
def api(tmp_path):
    with fresh_database("sqlite", tmp_path) as url, api_client(url) as client:
        yield SCMCalibClient("http://testserver", token=TOKEN, http_client=client)


def test_client_round_trip(api: SCMCalibClient) -> None:
    ds = api.upload_summary(summary_doc(1.0))
    assert ds["created"] is True and ds["source_kind"] == "summary"
    assert api.upload_summary(summary_doc(1.0))["id"] == ds["id"]
    assert api.dataset(ds["id"])["means"]["F"] == pytest.approx(51.0)
    assert [p["name"] for p in api.presets()] == ["quick", "1", "2a", "2b"]
    assert api.preset("2b")["seed"] == 3

    from_path = api.create_study(
        case=EXAMPLES / "quick.toml", dataset_ids=[ds["id"]], n_samples=30, max_stages=1
    )
    assert from_path["name"] == "quick" and from_path["n_samples"] == 30
    assert from_path["case"]["sampler"]["max_stages"] == 1
    from_case = api.create_study(
        case=load_case(EXAMPLES / "quick.toml"), dataset_ids=[ds["id"]], seed=99, name="q99"
    )
    assert from_case["seed"] == 99 and from_case["name"] == "q99"
    preset = api.create_study(preset="2a", dataset_ids=[ds["id"]], n_samples=40, batch_size=7)
    assert preset["batch_size"] == 7 and preset["parameter_names"][4] == "R"
    # stage 0: batches of 7 points, then shorter ones to the end of the stage
    assert preset["progress"]["batches_total"] == len(work_batches(40, 7)) == 8

    listed = api.studies(status="running")
    assert listed["total"] == 3
    assert api.stages(preset["id"])[0]["n_chains"] == 40
    assert api.events(preset["id"])[0]["kind"] == "study_created"
    # nothing runs the studies here: wait() gives up with the progress in its message
    with pytest.raises(SCMCalibTimeoutError, match=r"still running .* 0/40 evaluations"):
        api.wait(preset["id"], timeout=0.3, poll=0.1)
    assert api.cancel(preset["id"], reason="enough")["status"] == "cancelled"
    with pytest.raises(SCMCalibError) as err:
        api.cancel(preset["id"])
    assert err.value.status_code == 409


def test_client_errors(api: SCMCalibClient) -> None:
    with pytest.raises(SCMCalibError) as err:
        api.get_study(999)
    assert err.value.status_code == 404 and str(err.value) == "study 999 not found"
    with pytest.raises(SCMCalibError) as err:
        api.create_study(preset="1", dataset_ids=[5])
    assert err.value.status_code == 422 and str(err.value).startswith("dataset_ids:")
    with pytest.raises(SCMCalibError) as err:
        api.samples(1)
    assert err.value.status_code == 404
    with pytest.raises(SCMCalibError, match="case file"):
        api.create_study(case=EXAMPLES / "missing.toml", dataset_ids=[1])
    anonymous = SCMCalibClient("http://testserver", http_client=api._http)
    with pytest.raises(SCMCalibError) as err:
        anonymous.upload_summary(summary_doc())
    assert err.value.status_code == 401
