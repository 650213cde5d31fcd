"""Uploads and the dashboard with the lateral force Fy (issue 70): a steered wheel's summary
with ``lateral_force`` is stored with its Fy and shown; without its unit it is refused (422
naming ``lateral_force``) and nothing is stored; a page of straight datasets has no Fy
column."""

from __future__ import annotations

import pytest
from test_api_support import AUTH, api_client, detail, fresh_database, summary_doc

STEERED = (
    "# slip_angle: 60 deg\n# normal_load: 20.1 N\n# slip: -1\n# slip_convention: symmetric\n"
    "# n_trials: 3\nresponse,mean,sd,unit\nF,-29.78,0.9,N\nlateral_force,39.69,1.2,N\n"
    "z,51.4,0.8,mm\n"
)  # the CMU smooth wheel locked at 60 deg (examples/cmu_steering)


@pytest.fixture
def client(tmp_path):
    with fresh_database("sqlite", tmp_path) as url, api_client(url) as client:
        yield client


def _upload(client, text: str, name: str):
    return client.post(
        "/datasets", files={"file": (f"{name}.csv", text.encode(), "text/csv")}, headers=AUTH
    )


def test_a_steered_summary_is_stored_with_its_lateral_force_and_shown(client) -> None:
    straight = client.post("/datasets", json=summary_doc(), headers=AUTH)
    assert straight.status_code == 201
    page = client.get("/ui/f/datasets").text
    assert "F [N]" in page and "z [mm]" in page and "Fy [N]" not in page
    r = _upload(client, STEERED, "steered60")
    assert r.status_code == 201, r.text
    ds = r.json()
    assert ds["means"]["Fy"] == pytest.approx(39.69) and ds["conditions"]["slip_angle"] == 60.0
    assert "Fy [N]" in client.get("/ui/f/datasets").text  # the page now has one with Fy
    page = client.get(f"/ui/f/datasets/{ds['id']}").text
    assert '<th scope="row">Fy [N]</th>' in page


def test_a_lateral_force_without_its_unit_is_refused_and_nothing_stored(client) -> None:
    before = client.get("/datasets").json()["total"]
    r = _upload(client, STEERED.replace("lateral_force,39.69,1.2,N", "Fy,39.69,1.2,"), "bad")
    assert r.status_code == 422 and "lateral_force" in detail(r) and "unit" in detail(r)
    assert client.get("/datasets").json()["total"] == before
