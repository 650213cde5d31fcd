"""A steered study on the dashboard (issue 70): a real calibration of rows of
``examples/cmu_steering`` (the CMU smooth wheel at 0 and 30 deg, locked and at slip 0.9,
fitting F, Fy and z) and a prediction of its datasets, served by the app: the fit at the MAP
and the predictions come as charts of a column per slip angle, with Fy, the 95 % bands and the
measured points, and their SVG and PNG downloads draw the same grid."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from steering_fixtures import cmu_name, cmu_rows, cmu_summary
from test_api_support import AUTH, api_client, fresh_database, tiny_case, wait_ended

TIMEOUT = 300.0
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
ANGLES = (0.0, 30.0)
FY = "lateral force Fy [N]"


def steered_case() -> dict:
    """A case that fits F, Fy and z of the steered summaries in a few short stages."""
    case = tiny_case(params=("phi",), n_samples=12, max_stages=4)
    case["responses"] = ["F", "Fy", "z"]
    case["nominal"]["sigma_Fy"] = 10.0
    return case


def make_steered_study(client, rows: list[dict[str, float]]) -> tuple[int, int]:
    """(calibration id, prediction id) of the summaries of ``rows``, both completed;
    ``client``: a TestClient or an ``httpx.Client`` on a served app."""
    ids = []
    for row in rows:
        files = {"file": (f"{cmu_name(row)}.csv", cmu_summary(row).encode(), "text/csv")}
        r = client.post("/datasets", files=files, headers=AUTH)
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    body = {"case": steered_case(), "dataset_ids": ids, "name": "steered"}
    r = client.post("/studies", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    cal = r.json()["id"]
    assert wait_ended(client.get, f"/studies/{cal}", TIMEOUT)["status"] == "completed"
    body = {"study_id": cal, "dataset_ids": ids, "draws": 4, "name": "steered pred"}
    r = client.post("/predictions", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    pred = r.json()["id"]
    assert wait_ended(client.get, f"/predictions/{pred}", TIMEOUT)["status"] == "completed"
    return cal, pred


@pytest.fixture(scope="module")
def steered(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple]:
    directory = tmp_path_factory.mktemp("steered")
    with (
        fresh_database("sqlite", directory) as url,
        api_client(url, start_local_runtime=True, worker_concurrency=2) as client,
    ):
        rows = cmu_rows(ANGLES, rim_speeds=(0.0, 100.0))
        yield (client, *make_steered_study(client, rows), rows)


def _layers(panel: dict, kind: str) -> list[dict]:
    return [la for la in panel["layers"] if la["kind"] == kind]


def _ordered(lo: list, mid: list, hi: list) -> bool:
    return all(a <= b <= c for a, b, c in zip(lo, mid, hi, strict=True) if None not in (a, b, c))


def test_the_fit_of_a_steered_study_has_a_column_per_slip_angle(steered) -> None:
    client, cal, _, rows = steered
    r = client.get(f"/ui/figures/studies/{cal}/fit.json")
    assert r.status_code == 200, r.text
    chart = r.json()
    assert chart["columns"] == 2 and chart["reflow"] == "columns"
    panels = chart["panels"]
    assert [p["title"] for p in panels[:2]] == ["slip angle 0 deg", "slip angle 30 deg"]
    labels = [p["y"]["label"] for p in panels[::2]]
    assert labels == ["drawbar pull F [N]", "sinkage z [mm]", FY]
    for j, angle in enumerate(ANGLES):
        fy = panels[4 + j]
        (band,) = _layers(fy, "band")
        (sim,) = _layers(fy, "line")
        assert _ordered(band["lo"], sim["y"], band["hi"]) and None not in sim["y"]
        (pts,) = _layers(fy, "points")
        want = [r["lateral_force_N_mean"] for r in rows if r["slip_angle_deg"] == angle]
        assert pts["y"] == pytest.approx(want, rel=1e-4)
    assert "per slip angle" in chart["title"]


def test_the_predictions_of_a_steered_study_have_a_column_per_slip_angle(steered) -> None:
    client, cal, pred, rows = steered
    # the prediction's page and its calibration's posterior predictive panel draw this chart
    chart = client.get(f"/ui/figures/studies/{pred}/predictions.json").json()
    assert chart["columns"] == 2
    panels = chart["panels"]
    labels = [p["y"]["label"] for p in panels[::2]]  # T predicted too, though not measured
    assert labels == ["drawbar pull F [N]", "torque T [N m]", "sinkage z [mm]", FY]
    for j, angle in enumerate(ANGLES):
        mine = [r for r in rows if r["slip_angle_deg"] == angle]
        fy = panels[6 + j]
        (bars,) = _layers(fy, "errorbars")
        assert len(bars["x"]) == len(mine) and _ordered(bars["lo"], bars["y"], bars["hi"])
        (pts,) = _layers(fy, "points")  # measured, used in the calibration
        assert pts["y"] == pytest.approx([r["lateral_force_N_mean"] for r in mine], rel=1e-4)
    for name, study in (("fit", cal), ("predictions", pred)):
        svg = client.get(f"/ui/figures/studies/{study}/{name}.svg")
        assert svg.status_code == 200 and b"slip angle 30 deg" in svg.content
        png = client.get(f"/ui/figures/studies/{study}/{name}.png")
        assert png.status_code == 200 and png.content.startswith(PNG_MAGIC)
