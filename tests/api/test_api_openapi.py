"""The OpenAPI document says what the server answers: every error is ``ErrorOut`` (one line in
``detail``), the bearer-token scheme and the operations that need it, 401 before the body is
read, no 400, 405 with every allowed method, query patterns that are the server's own rules.

(``test_api_schemathesis`` checks the same against a real server by fuzzing; these are the
fast, in-process cases.)
"""

from __future__ import annotations

import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_api_support import AUTH, api_client, detail, fresh_database

from services.api.params import STATUS_PATTERN, parse_statuses
from services.api.routes import errors
from services.api.routes.pooled import IDS_PATTERN
from services.store.models import STUDY_STATUSES
from services.studies.kinds.registry import KINDS

#: health answers whose 503 body is their own model (what failed), not ErrorOut
HEALTH_503 = ("/health/ready", "/health/live")
WRITES = {("post", "/datasets"), ("post", "/studies"), ("post", "/studies/{study_id}/cancel")}
WRITES |= {("post", "/sensitivity")}
#: every kind with its own collection (services.studies.kinds.base.KindHttp) is written by POST
WRITES |= {("post", k.http.path) for k in KINDS.values() if k.http is not None}


@pytest.fixture(scope="module")
def url(tmp_path_factory: pytest.TempPathFactory):
    with fresh_database("sqlite", tmp_path_factory.mktemp("openapi")) as url:
        yield url


@pytest.fixture(scope="module")
def client(url: str):
    with api_client(url) as client:
        yield client


def _operations(spec: dict):
    for path, ops in spec["paths"].items():
        for method, op in ops.items():
            yield method, path, op


@pytest.mark.parametrize("reads_need_token", [False, True])
def test_errors_and_security_in_the_document(url: str, reads_need_token: bool) -> None:
    with api_client(url, read_requires_token=reads_need_token) as client:
        spec = client.get("/openapi.json").json()
    schemas = spec["components"]["schemas"]
    assert "HTTPValidationError" not in schemas and "ValidationError" not in schemas
    assert schemas["ErrorOut"]["properties"]["detail"]["type"] == "string"
    scheme = spec["components"]["securitySchemes"]["bearerAuth"]
    assert scheme["type"] == "http" and scheme["scheme"] == "bearer"
    secured = set()
    for method, path, op in _operations(spec):
        for code, response in op["responses"].items():
            if int(code) < 400 or (code == "503" and path in HEALTH_503):
                continue
            ref = response["content"]["application/json"]["schema"]["$ref"]
            assert ref == "#/components/schemas/ErrorOut", (method, path, code)
        if method == "post":
            assert {"413", "422"} <= set(op["responses"]), (method, path)
        if op.get("security"):
            assert op["security"] == [{"bearerAuth": []}]
            assert op["responses"]["401"]["headers"]["WWW-Authenticate"]["required"] is True
            secured.add((method, path))
    everything = {(m, p) for m, p, _ in _operations(spec) if not p.startswith("/health")}
    assert secured == (everything if reads_need_token else WRITES)


def test_errors_documents_the_headers_sent_with_401_and_429() -> None:
    doc = errors(401, 404, 429)
    assert set(doc[401]["headers"]) == {"WWW-Authenticate"}
    assert doc[429]["headers"]["Retry-After"]["schema"]["type"] == "integer"
    assert "headers" not in doc[404]


def test_the_token_is_checked_before_the_body(url: str) -> None:
    """Without a valid token a write answers 401, whatever its body: malformed or too deep
    JSON, a body over the size limit, an invalid path id. Reads that need no token still
    validate their body."""
    deep = b"[" * 100 + b"]" * 100
    with api_client(url, upload_max_bytes=1000) as client:
        json_headers = {"content-type": "application/json"}
        for path, body in (
            ("/studies", b'{"preset": "1", "dataset_ids": [1'),
            ("/studies", b"\xff\xfe}"),
            ("/sensitivity", deep),
            ("/studies/abc/cancel", b"{"),
            ("/datasets", b"x" * 100_000),  # over the upload limit: 413 with a token
        ):
            for headers in (json_headers, {**json_headers, "Authorization": "Bearer wrong"}):
                r = client.post(path, content=body, headers=headers)
                assert r.status_code == 401, (path, r.text)
                assert r.headers["www-authenticate"] == "Bearer"
                assert "token" in detail(r)
        r = client.post("/pooled", content=b"{", headers=json_headers)
        assert r.status_code == 422 and "invalid JSON" in detail(r)
        r = client.post("/studies", content=b"{", headers={**json_headers, **AUTH})
        assert r.status_code == 422 and "invalid JSON" in detail(r)
    with api_client(url, read_requires_token=True) as client:
        r = client.post("/pooled", content=b"{", headers={"content-type": "application/json"})
        assert r.status_code == 401


def test_a_body_that_cannot_be_parsed_is_422_not_400(client) -> None:
    r = client.post(
        "/studies",
        content=b'{"name": "\xc3("}',
        headers={**AUTH, "content-type": "application/json"},
    )
    assert r.status_code == 422 and detail(r).startswith("body: invalid JSON: not UTF-8")
    fields = {f"f{k}": "1" for k in range(12)}
    r = client.post(
        "/datasets", data=fields, files={"file": ("a.csv", b"x", "text/csv")}, headers=AUTH
    )
    assert r.status_code == 422, r.text
    assert detail(r).startswith("body: invalid multipart form: Too many fields")


@pytest.mark.parametrize(
    ("method", "path", "allowed"),
    [
        ("OPTIONS", "/studies", "GET, POST"),
        ("DELETE", "/studies/1", "GET"),
        ("PUT", "/pooled", "GET, POST"),
        ("GET", "/studies/1/cancel", "POST"),
        ("PATCH", "/datasets", "GET, POST"),
        ("DELETE", "/health", "GET"),
    ],
)
def test_405_names_every_allowed_method(client, method: str, path: str, allowed: str) -> None:
    r = client.request(method, path)
    assert r.status_code == 405 and r.headers["allow"] == allowed
    assert f"allowed: {allowed}" in detail(r)


_STATUS_TEXT = st.lists(
    st.sampled_from([*STUDY_STATUSES, "", " ", ",", "queue", "\t", "Running", "x"]), max_size=6
).map("".join)


@given(_STATUS_TEXT)
def test_the_status_pattern_is_what_the_server_accepts(text: str) -> None:
    matches = re.fullmatch(STATUS_PATTERN.removesuffix("$") + r"\Z", text) is not None
    try:
        parse_statuses(text)
        accepted = True
    except Exception:
        accepted = False
    assert matches == accepted, text


@settings(max_examples=60, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.sampled_from(["1", "23", "", " ", ",", "x", "-1", "+2", "\t"]), max_size=6))
def test_the_study_ids_pattern_is_what_the_server_accepts(client, parts: list[str]) -> None:
    """An item of ``GET /pooled?study_ids=`` the pattern refuses is answered 422 naming it
    ("not a study id" or "no study id in"); one it admits gets past that parsing (to 422
    "no study with id" or "listed twice", since the database has no study)."""
    text = "".join(parts)
    matches = re.fullmatch(IDS_PATTERN.removesuffix("$") + r"\Z", text) is not None
    r = client.get("/pooled", params={"study_ids": text})
    assert r.status_code == 422
    message = detail(r)
    refused = "not a study id" in message or "no study id in" in message
    assert refused != matches, (text, message)


#: JSON values of every type, for the fields of a request body
JSON_VALUES = [True, False, 0, 1, 7.0, 1e3, 1.5, -1, "1", "", None, [], [1], [True], ["1"], {}]


def _bodies(base: dict, fields: list[str]):
    for field in fields:
        for value in JSON_VALUES:
            yield {**base, field: value}


@pytest.mark.parametrize(
    ("model", "base"),
    [
        ("PooledRequest", {"study_ids": [1, 2]}),
        ("PredictionRequest", {"study_id": 1, "dataset_ids": [1]}),
        ("CancelRequest", {}),
    ],
)
def test_request_bodies_accept_what_their_schema_accepts(model: str, base: dict) -> None:
    """A body the model's JSON Schema (as the OpenAPI document gives it) admits is accepted
    and one it refuses is refused, field by field and JSON type by JSON type: no conversion
    across JSON types (``false`` as a seed, ``0`` as a flag, ``"1"`` as an id; schemathesis
    found both kinds of disagreement) and integral numbers as integers (JSON Schema's rule).
    PredictionRequest's choice of dataset_ids or conditions is the route's (its schema's
    oneOf): those two fields are left out here."""
    import jsonschema_rs
    from pydantic import ValidationError

    from services.api import schemas
    from services.studies.kinds import prediction

    cls = getattr(schemas, model, None) or getattr(prediction, model)
    validator = jsonschema_rs.validator_for(cls.model_json_schema())
    fields = [f for f in cls.model_fields if f not in ("dataset_ids", "conditions")]
    checked = 0
    for body in _bodies(base, fields):
        try:
            cls.model_validate(body)
            accepted = True
        except ValidationError:
            accepted = False
        assert accepted == validator.is_valid(body), body
        checked += 1
    assert checked == len(fields) * len(JSON_VALUES)
