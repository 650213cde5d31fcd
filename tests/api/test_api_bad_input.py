"""Bad requests are refused with a 4xx naming the field, and change nothing in the database.

Runs on SQLite and on a fresh PostgreSQL database. Every case compares the row counts of all
tables (datasets, studies, stages, work_batches, samples, events, study_datasets) before and
after the request.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest
from test_api_support import (
    AUTH,
    BACKENDS,
    LOG,
    TOKEN,
    api_client,
    detail,
    fresh_database,
    row_counts,
    summary_doc,
    tiny_case,
    upload_file,
)

#: one worker runs the module: its module fixtures (a served API, a results folder) are
#: built once, not once per pytest-xdist worker
pytestmark = pytest.mark.xdist_group("test_api_bad_input")

UPLOAD_LIMIT = 600_000  # the example log has 430 244 bytes


@dataclass
class Env:
    client: Any
    url: str
    dataset_id: int
    preset: dict[str, Any]


@pytest.fixture(scope="module", params=BACKENDS)
def env(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    directory = tmp_path_factory.mktemp(f"bad-{request.param}")
    with (
        fresh_database(request.param, directory) as url,
        api_client(url, upload_max_bytes=UPLOAD_LIMIT) as client,
    ):
        r = upload_file(client)
        assert r.status_code == 201, r.text
        preset = client.get("/presets/1").json()
        yield Env(client, url, r.json()["id"], preset)


def _case(env: Env, change: Callable[[dict], None]) -> dict:
    doc = copy.deepcopy(env.preset)
    change(doc)
    return doc


def _unknown_parameter(doc: dict) -> None:
    doc["parameters"]["k_x"] = {"dist": "uniform", "lower": 0.0, "upper": 1.0}


def _lower_above_upper(doc: dict) -> None:
    doc["parameters"]["k_phi"]["lower"] = 2e10


def _prior_beyond_field(doc: dict) -> None:
    doc["parameters"]["phi"] = {"dist": "uniform", "lower": 20.0, "upper": 95.0}


def _lower_equals_upper(doc: dict) -> None:
    doc["parameters"]["phi"] = {"dist": "uniform", "lower": 30.0, "upper": 30.0}


def _unknown_resampling(doc: dict) -> None:
    doc.setdefault("sampler", {})["resampling"] = "stratified"


def _jumps_one(doc: dict) -> None:
    doc.setdefault("sampler", {})["surrogate_jumps"] = 1.0


def _bad_log() -> bytes:
    return LOG.read_bytes().replace(b"torque [Nm]", b"torque [furlong]")


#: line of the example log's column header (after its metadata lines)
HEADER_LINE = next(
    i for i, line in enumerate(LOG.read_text().splitlines(), 1) if line.startswith("time")
)


def _ragged_log() -> bytes:
    lines = LOG.read_bytes().split(b"\n")
    lines[200] = lines[200] + b",1.0"
    return b"\n".join(lines)


def _absurd_log() -> bytes:
    """Drawbar pull of 1e308 N on line 301: finite, but its square overflows."""
    lines = LOG.read_bytes().split(b"\n")
    cells = lines[300].split(b",")
    cells[1] = b"1e308"
    lines[300] = b",".join(cells)
    return b"\n".join(lines)


# (id, method, path, request kwargs (a function of env), status, words the message must contain)
CASES: list[tuple[str, str, str, Callable[[Env], dict], int, tuple[str, ...]]] = [
    ("malformed-json", "POST", "/studies",
     lambda e: {"content": b'{"preset": "1", "dataset_ids": [1',
                "headers": {**AUTH, "content-type": "application/json"}},
     422, ("body", "invalid JSON")),
    ("json-not-object", "POST", "/studies", lambda e: {"json": [1, 2]}, 422, ("body",)),
    ("unknown-preset", "POST", "/studies",
     lambda e: {"json": {"preset": "3c", "dataset_ids": [e.dataset_id]}}, 422,
     ("preset", "3c")),
    ("preset-and-case", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "case": e.preset, "dataset_ids": [e.dataset_id]}},
     422, ("preset",)),
    ("unknown-parameter", "POST", "/studies",
     lambda e: {"json": {"case": _case(e, _unknown_parameter), "dataset_ids": [e.dataset_id]}},
     422, ("case.parameters.k_x", "unknown parameter")),
    ("prior-lower-above-upper", "POST", "/studies",
     lambda e: {"json": {"case": _case(e, _lower_above_upper), "dataset_ids": [e.dataset_id]}},
     422, ("case.parameters.k_phi",)),
    ("prior-beyond-field-range", "POST", "/studies",
     lambda e: {"json": {"case": _case(e, _prior_beyond_field), "dataset_ids": [e.dataset_id]}},
     422, ("case.parameters.phi", "simulator's range")),
    ("prior-lower-equals-upper", "POST", "/studies",
     lambda e: {"json": {"case": _case(e, _lower_equals_upper), "dataset_ids": [e.dataset_id]}},
     422, ("case.parameters.phi",)),
    ("unknown-resampling", "POST", "/studies",
     lambda e: {"json": {"case": _case(e, _unknown_resampling), "dataset_ids": [e.dataset_id]}},
     422, ("case.sampler.resampling", "'systematic' or 'multinomial'")),
    ("surrogate-jumps-one", "POST", "/studies",
     lambda e: {"json": {"case": _case(e, _jumps_one), "dataset_ids": [e.dataset_id]}},
     422, ("case.sampler.surrogate_jumps", "less than 1")),
    ("unknown-dataset-id", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "dataset_ids": [e.dataset_id + 1000]}}, 422,
     ("dataset_ids", str(1000 + 1))),
    ("no-dataset", "POST", "/studies", lambda e: {"json": {"preset": "1"}}, 422,
     ("dataset_ids",)),
    ("unknown-override", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "dataset_ids": [e.dataset_id], "n_sample": 100}},
     422, ("n_sample", "unknown field")),
    ("n-samples-too-small", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "dataset_ids": [e.dataset_id], "n_samples": 3}},
     422, ("n_samples",)),
    ("negative-seed", "POST", "/studies",
     lambda e: {"json": {"preset": "2a", "dataset_ids": [e.dataset_id], "seed": -1}}, 422,
     ("seed",)),
    ("dataset-id-not-int", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "dataset_ids": ["one"]}}, 422, ("dataset_ids.0",)),
    ("missing-token", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "dataset_ids": [e.dataset_id]}, "headers": {}}, 401,
     ("missing API token", "Authorization: Bearer")),
    ("wrong-token", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "dataset_ids": [e.dataset_id]},
                "headers": {"Authorization": "Bearer not-" + TOKEN}},
     401, ("invalid API token",)),
    ("wrong-scheme", "POST", "/studies",
     lambda e: {"json": {"preset": "1", "dataset_ids": [e.dataset_id]},
                "headers": {"Authorization": f"Basic {TOKEN}"}},
     401, ("Bearer",)),
    ("upload-missing-token", "POST", "/datasets",
     lambda e: {"files": {"file": ("x.csv", LOG.read_bytes(), "text/csv")}, "headers": {}},
     401, ("missing API token",)),
    ("upload-over-limit-by-one", "POST", "/datasets",
     lambda e: {"files": {"file": ("big.csv", b"#" * (UPLOAD_LIMIT + 1), "text/csv")}},
     413, ("file", str(UPLOAD_LIMIT))),
    ("upload-far-over-limit", "POST", "/datasets",
     lambda e: {"files": {"file": ("big.csv", b"#" * (3 * UPLOAD_LIMIT), "text/csv")}},
     413, ("file", str(UPLOAD_LIMIT))),
    ("json-summary-over-limit", "POST", "/datasets",
     lambda e: {"content": b" " * (UPLOAD_LIMIT + 10),
                "headers": {**AUTH, "content-type": "application/json"}},
     413, ("body", str(UPLOAD_LIMIT))),
    ("csv-unknown-unit", "POST", "/datasets",
     lambda e: {"files": {"file": ("bad.csv", _bad_log(), "text/csv")}}, 422,
     ("file bad.csv", f"line {HEADER_LINE}", "torque [furlong]", "unit")),
    ("csv-ragged-row", "POST", "/datasets",
     lambda e: {"files": {"file": ("ragged.csv", _ragged_log(), "text/csv")}}, 422,
     ("file ragged.csv", "line 201")),
    ("csv-absurd-value", "POST", "/datasets",
     lambda e: {"files": {"file": ("absurd.csv", _absurd_log(), "text/csv")}}, 422,
     ("file absurd.csv", "line 301, column 'drawbar_pull [N]'", "plausible range")),
    ("summary-absurd-mean", "POST", "/datasets",
     lambda e: {"json": {**summary_doc(8.0), "responses": {"F": {"mean": 1e308, "sd": 1.0}}}},
     422, ("body", "response 'F': mean", "plausible range")),
    ("csv-not-utf8", "POST", "/datasets",
     lambda e: {"files": {"file": ("bin.csv", b"\xff\xfe\x00binary", "text/csv")}}, 422,
     ("file bin.csv", "UTF-8")),
    ("csv-missing-columns", "POST", "/datasets",
     lambda e: {"files": {"file": ("cols.csv", b"time [s],F [N]\n0,1\n1,2\n", "text/csv")}},
     422, ("file cols.csv",)),
    ("metadata-not-json", "POST", "/datasets",
     lambda e: {"files": {"file": ("m.csv", LOG.read_bytes(), "text/csv")},
                "data": {"metadata": "{W: 315"}},
     422, ("metadata", "not valid JSON")),
    ("metadata-conflicts-with-file", "POST", "/datasets",
     lambda e: {"files": {"file": ("m.csv", LOG.read_bytes(), "text/csv")},
                "data": {"metadata": '{"W": 100.0}'}},
     422, ("file m.csv", "W")),
    ("upload-without-file", "POST", "/datasets",
     lambda e: {"data": {"metadata": "{}"}, "files": {"other": ("x", b"1", "text/plain")}},
     422, ("file", "required")),
    ("upload-wrong-content-type", "POST", "/datasets",
     lambda e: {"content": b"time,F\n", "headers": {**AUTH, "content-type": "text/csv"}},
     415, ("multipart/form-data",)),
    ("summary-without-response", "POST", "/datasets",
     lambda e: {"json": {**summary_doc(7.0), "responses": {}}},
     422, ("body", "no response")),
    ("cancel-unknown-study", "POST", "/studies/999/cancel", lambda e: {}, 404, ("study 999",)),
    ("unknown-status-filter", "GET", "/studies?status=bogus", lambda e: {}, 422,
     ("status", "bogus")),
    ("limit-zero", "GET", "/studies?limit=0", lambda e: {}, 422, ("query.limit",)),
    ("unknown-dataset", "GET", "/datasets/999", lambda e: {}, 404, ("dataset 999",)),
    ("unknown-preset-get", "GET", "/presets/9", lambda e: {}, 404, ("preset",)),
    ("pool-unknown-study", "POST", "/pooled", lambda e: {"json": {"study_ids": [999]}}, 422,
     ("study_ids", "999")),
    # sensitivity (Morris) studies
    ("sens-malformed-json", "POST", "/sensitivity",
     lambda e: {"content": b'{"preset": "1", "dataset_id": ',
                "headers": {**AUTH, "content-type": "application/json"}},
     422, ("body", "invalid JSON")),
    ("sens-unknown-dataset", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id + 1000}}, 422,
     ("dataset_id", "no dataset")),
    ("sens-no-dataset", "POST", "/sensitivity", lambda e: {"json": {"preset": "1"}}, 422,
     ("dataset_id", "field required")),
    ("sens-unknown-preset", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "7", "dataset_id": e.dataset_id}}, 422, ("preset", "7")),
    ("sens-bounds-lower-above-upper", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id,
                         "bounds": {"c": [500.0, 100.0]}}},
     422, ("bounds.c", "lower < upper")),
    ("sens-bounds-unknown-factor", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id,
                         "bounds": {"R": [0.1, 0.2]}}},
     422, ("bounds", "'R'", "not screened")),
    ("sens-bounds-not-a-pair", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id, "bounds": {"c": [1.0]}}},
     422, ("bounds.c",)),
    ("sens-bounds-outside-simulator", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id,
                         "bounds": {"phi": [80.0, 120.0]}}},
     422, ("bounds.phi", "less than 90")),
    ("sens-odd-levels", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id, "levels": 5}}, 422,
     ("levels", "even")),
    ("sens-one-trajectory", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id, "r": 1}}, 422, ("r",)),
    ("sens-unknown-field", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id, "trajectories": 4}}, 422,
     ("trajectories", "unknown field")),
    ("sens-missing-token", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id}, "headers": {}}, 401,
     ("missing API token",)),
    ("sens-wrong-token", "POST", "/sensitivity",
     lambda e: {"json": {"preset": "1", "dataset_id": e.dataset_id},
                "headers": {"Authorization": "Bearer x" + TOKEN}},
     401, ("invalid API token",)),
    ("sens-unknown-study", "GET", "/sensitivity/999", lambda e: {}, 404, ("study 999",)),
    ("unknown-kind-filter", "GET", "/studies?kind=sobol", lambda e: {}, 422,
     ("query.kind",)),
    ("case-file-not-toml", "POST", "/cases/check",
     lambda e: {"json": {"toml": "[parameters\nphi = 1\n"}},
     422, ("toml: case file is not valid TOML", "line 1")),
    ("case-file-bad-field", "POST", "/cases/check",
     lambda e: {"json": {"toml": 'name = "x"\n[parameters]\nphi = { dist = "gamma" }\n'}},
     422, ("toml: parameters.phi",)),
    ("case-file-empty", "POST", "/cases/check", lambda e: {"json": {"toml": ""}}, 422,
     ("toml",)),
    ("case-file-too-long", "POST", "/cases/check",
     lambda e: {"json": {"toml": "#" * 200_001}}, 422, ("toml", "200000")),
    ("case-file-no-text", "POST", "/cases/check", lambda e: {"json": {"text": "x"}}, 422,
     ("text", "unknown field")),
]  # fmt: skip


@pytest.mark.parametrize(
    ("method", "path", "kwargs", "status", "words"),
    [pytest.param(*c[1:], id=c[0]) for c in CASES],
)
def test_bad_request_changes_nothing(env: Env, method, path, kwargs, status, words) -> None:
    request = kwargs(env)
    request.setdefault("headers", AUTH)
    before = row_counts(env.url)
    r = env.client.request(method, path, **request)
    after = row_counts(env.url)
    assert r.status_code == status, r.text
    message = detail(r)
    for word in words:
        assert word in message, message
    assert "\n" not in message
    assert after == before
    if status == 401:
        assert r.headers.get("www-authenticate") == "Bearer"


def test_identical_upload_is_answered_before_parsing(
    env: Env, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same bytes, metadata and offset as an earlier upload: 200 with the stored record
    from the upload hash alone (the parser, replaced by one that fails, is never called); other
    metadata is parsed again."""
    from services.api.routes import datasets as route

    def no_parsing(*args: Any) -> None:
        raise AssertionError("parsed again")

    monkeypatch.setattr(route, "parse_upload", no_parsing)
    before = row_counts(env.url)
    again = upload_file(env.client)
    assert again.status_code == 200, again.text
    assert again.json()["id"] == env.dataset_id and again.json()["created"] is False
    assert row_counts(env.url) == before
    with pytest.raises(AssertionError, match="parsed again"):
        upload_file(env.client, offset="41")


def test_identical_upload_returns_same_dataset(env: Env) -> None:
    before = row_counts(env.url)
    again = upload_file(env.client)
    assert again.status_code == 200, again.text
    assert again.json()["id"] == env.dataset_id and again.json()["created"] is False
    assert row_counts(env.url) == before

    doc = summary_doc(3.5)
    first = env.client.post("/datasets", json=doc, headers=AUTH)
    second = env.client.post("/datasets", json=doc, headers=AUTH)
    assert (first.status_code, second.status_code) == (201, 200)
    assert first.json()["id"] == second.json()["id"]
    assert first.headers["location"] == f"/datasets/{first.json()['id']}"
    after = row_counts(env.url)
    assert after["datasets"] == before["datasets"] + 1
    assert after["events"] == before["events"] + 1  # one "dataset_added"


def test_case_invalid_on_a_dataset_at_the_prior_medians_is_refused(env: Env) -> None:
    """A 1.5 cm wheel (from the dataset) with the case's 9 mm grousers cannot be built
    (grousers at most half the radius): 422 naming the dataset and the reason, before any
    study is stored."""
    doc = summary_doc(9.0, name="small wheel")
    doc["conditions"] = {**doc["conditions"], "R": 0.015}
    small = env.client.post("/datasets", json=doc, headers=AUTH)
    assert small.status_code == 201, small.text
    before = row_counts(env.url)
    r = env.client.post(
        "/studies", json={"case": tiny_case(), "dataset_ids": [small.json()["id"]]}, headers=AUTH
    )
    assert r.status_code == 422, r.text
    assert detail(r) == (
        f"dataset_ids: dataset {small.json()['id']} (small wheel): invalid simulator "
        "configuration at the prior medians: grouser_height must be at most half the rim "
        "radius R"
    )
    assert row_counts(env.url) == before
