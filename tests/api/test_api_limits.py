"""Hard limits (issue 9): every one refused with 422 (404 for an id that cannot exist) naming
the field, before anything is stored: the database's row counts are unchanged."""

from __future__ import annotations

import json

import pytest
from test_api_support import AUTH, LOG, api_client, detail, fresh_database, row_counts, tiny_case
from test_api_support import upload_file as upload

BIG = 2**63  # one more than a BIGINT holds


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    """(client, url, dataset id) on a fresh SQLite database with the example log."""
    directory = tmp_path_factory.mktemp("limits")
    with fresh_database("sqlite", directory) as url, api_client(url) as client:
        r = upload(client, LOG)
        assert r.status_code == 201, r.text
        yield client, url, r.json()["id"]


def _case(**simulator):
    case = tiny_case()
    case["simulator"].update(simulator)
    return case


STUDY_LIMITS = [
    # (overrides of the request, case simulator changes, field named first in the message)
    ({"n_samples": 1e9}, {}, "n_samples: samples per stage 1000000000 is over the limit"),
    ({"max_stages": 10_000}, {}, "max_stages: stages 10000 is over the limit of 100"),
    ({"n_samples": 20_000, "batch_size": 1}, {}, "batch_size: 1 cuts 20000 samples"),
    (
        {"n_samples": 20_000, "n_steps": 1000, "max_stages": 100, "moves": "resample-move"},
        {},
        "n_samples: up to 2e+09 model runs",
    ),
    ({}, {"duration": 1e9, "dt": 0.04}, "simulator.duration: time steps per run"),
    ({}, {"dt": 1e-9}, "simulator.dt: time steps per run (duration / dt) 8e+09"),
    ({}, {"output_rate": 1e9}, "simulator.output_rate: output rate [Hz] 1e+09"),
    # a fine grid over a long run: 0.5 mm cells, 2000 s at the log's 0.01 m/s
    ({}, {"dx": 0.0005, "duration": 2000.0, "dt": 0.04}, "simulator.dx: dataset"),
]


@pytest.mark.parametrize(("overrides", "simulator", "message"), STUDY_LIMITS)
def test_study_limits(env, overrides, simulator, message) -> None:
    client, url, dataset_id = env
    before = row_counts(url)
    body = {"case": _case(**simulator), "dataset_ids": [dataset_id], **overrides}
    r = client.post("/studies", json=body, headers=AUTH)
    assert r.status_code == 422, r.text
    assert detail(r).startswith(message), detail(r)
    assert "SCM_CALIB_MAX_" in detail(r)
    assert row_counts(url) == before


def test_datasets_per_study(env) -> None:
    client, url, _ = env
    before = row_counts(url)
    r = client.post(
        "/studies", json={"case": tiny_case(), "dataset_ids": list(range(1, 52))}, headers=AUTH
    )
    assert r.status_code == 422 and detail(r).startswith("dataset_ids: datasets 51 is over")
    assert row_counts(url) == before


def test_sensitivity_limits(env) -> None:
    client, url, dataset_id = env
    before = row_counts(url)
    r = client.post(
        "/sensitivity",
        json={"case": tiny_case(), "dataset_id": dataset_id, "r": 1000, "batch_size": 1},
        headers=AUTH,
    )
    assert r.status_code == 422 and detail(r).startswith("batch_size: 1 cuts 7000 samples")
    r = client.post(
        "/sensitivity",
        json={"case": _case(output_rate=1e6), "dataset_id": dataset_id},
        headers=AUTH,
    )
    assert r.status_code == 422 and detail(r).startswith("simulator.output_rate")
    r = client.post("/sensitivity", json={"case": tiny_case(), "dataset_id": BIG}, headers=AUTH)
    assert r.status_code == 422 and detail(r).startswith("dataset_id: ")
    assert row_counts(url) == before


@pytest.mark.parametrize(
    "path",
    [
        f"/datasets/{BIG}",
        f"/datasets/{BIG}/series",
        f"/studies/{BIG}",
        f"/studies/{BIG}/stages",
        f"/studies/{BIG}/stages/0/samples",
        f"/studies/1/stages/{BIG}/samples.csv",
        f"/studies/{BIG}/summary",
        f"/studies/{BIG}/events",
        f"/sensitivity/{BIG}",
        "/studies/-1",
    ],
)
def test_ids_a_database_cannot_hold_are_not_found(env, path) -> None:
    client, _, _ = env
    r = client.get(path)
    assert r.status_code == 404, (path, r.text)
    assert "not found" in detail(r)


@pytest.mark.parametrize(
    ("method", "path", "kwargs", "field"),
    [
        ("get", "/studies", {"params": {"offset": BIG}}, "query.offset"),
        ("get", "/datasets", {"params": {"offset": BIG}}, "query.offset"),
        ("get", "/studies/1/events", {"params": {"after_id": BIG}}, "query.after_id"),
        ("post", "/pooled", {"json": {"study_ids": [BIG]}}, "study_ids.0"),
        ("get", "/pooled", {"params": {"study_ids": str(BIG)}}, "query.study_ids"),
        ("post", "/studies", {"json": {"preset": "1", "dataset_ids": [BIG]}}, "dataset_ids.0"),
        ("post", "/studies", {"json": {"preset": "1", "n_samples": BIG}}, "n_samples"),
        ("post", "/studies", {"json": {"preset": "1", "batch_size": BIG}}, "batch_size"),
    ],
)
def test_integers_a_database_cannot_hold_are_refused(env, method, path, kwargs, field) -> None:
    client, url, _ = env
    before = row_counts(url)
    r = getattr(client, method)(path, headers=AUTH, **kwargs)
    assert r.status_code == 422, (path, r.text)
    assert detail(r).startswith(field), detail(r)
    assert row_counts(url) == before


def _nested(depth: int) -> str:
    """A JSON object nested ``depth`` levels deep (as text: json.dumps would recurse)."""
    return '{"a": ' * (depth - 1) + '{"x": 1}' + "}" * (depth - 1)


def test_json_nesting_depth(env) -> None:
    client, url, dataset_id = env
    before = row_counts(url)
    text = json.dumps(tiny_case())[:-1] + ', "deep": ' + _nested(5000) + "}"
    r = client.post(  # json.loads alone would recurse past Python's limit
        "/studies",
        content=f'{{"case": {text}, "dataset_ids": [{dataset_id}]}}',
        headers={**AUTH, "Content-Type": "application/json"},
    )
    assert r.status_code == 422 and detail(r).startswith("body: JSON nesting depth 5002 is over")
    r = client.post(
        "/datasets", content=_nested(40), headers={**AUTH, "Content-Type": "application/json"}
    )
    assert r.status_code == 422 and detail(r).startswith("body: JSON nesting depth 40")
    r = upload(client, LOG, metadata=_nested(3000))
    assert r.status_code == 422 and detail(r).startswith("metadata: JSON nesting depth 3000")
    # strings holding brackets do not count
    r = client.post(
        "/studies",
        json={"case": tiny_case(), "dataset_ids": [dataset_id], "name": "[[[[{{{{" * 30},
        headers=AUTH,
    )
    assert r.status_code == 422 and detail(r).startswith("name: "), detail(r)  # too long
    assert row_counts(url) == before
