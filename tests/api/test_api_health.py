"""Health and readiness, token policy for reads, OpenAPI."""

from __future__ import annotations

import pytest
from test_api_support import (
    AUTH,
    BACKENDS,
    api_client,
    detail,
    free_port,
    fresh_database,
    summary_doc,
)

from services.store.migrate import downgrade, upgrade


@pytest.mark.parametrize("backend", BACKENDS)
def test_ready_follows_the_schema_revision(backend: str, tmp_path) -> None:
    with fresh_database(backend, tmp_path) as url, api_client(url) as client:
        health = client.get("/health").json()
        assert health["status"] == "ok" and health["mode"] == "embedded"
        ready = client.get("/health/ready")
        assert ready.status_code == 200, ready.text
        assert ready.json()["checks"]["database"]["ok"] is True

        downgrade(url, "base")
        r = client.get("/health/ready")
        assert r.status_code == 503
        body = r.json()
        assert body["status"] == "not ready" and body["checks"]["database"]["ok"] is False
        assert "database" in body["detail"] and "base" in body["detail"]
        assert "scm-calib db upgrade" in body["detail"]
        assert client.get("/health").status_code == 200  # liveness does not care
        r = client.get("/studies")
        assert r.status_code == 503 and "database" in detail(r)

        upgrade(url)
        assert client.get("/health/ready").status_code == 200
        assert client.get("/studies").json()["total"] == 0


def test_ready_checks_the_broker_in_distributed_mode(tmp_path) -> None:
    with fresh_database("sqlite", tmp_path) as url:
        with api_client(url, broker_url="redis://127.0.0.1:6379/15") as client:
            assert client.get("/health").json()["mode"] == "distributed"
            r = client.get("/health/ready")
            assert r.status_code == 200, r.text
            assert r.json()["checks"]["broker"]["ok"] is True
        dead = f"redis://127.0.0.1:{free_port()}/0"
        with api_client(url, broker_url=dead) as client:
            r = client.get("/health/ready")
            assert r.status_code == 503
            assert r.json()["checks"]["database"]["ok"] is True
            assert "broker: cannot reach" in r.json()["detail"]


def test_reads_need_a_token_only_when_configured(tmp_path) -> None:
    with fresh_database("sqlite", tmp_path) as url:
        with api_client(url) as client:
            assert client.get("/studies").status_code == 200
            assert client.get("/presets").status_code == 200
        with api_client(url, read_requires_token=True) as client:
            for path in ("/studies", "/datasets", "/presets", "/presets/1", "/studies/1"):
                r = client.get(path)
                assert r.status_code == 401 and "missing API token" in detail(r), path
            assert client.get("/studies", headers=AUTH).status_code == 200
            assert client.get("/health").status_code == 200
            assert client.get("/health/ready").status_code == 200
            r = client.post("/pooled", json={"study_ids": [1]})
            assert r.status_code == 401
        with api_client(url, api_tokens=[]) as client:
            r = client.post("/datasets", json=summary_doc(), headers=AUTH)
            assert r.status_code == 401 and "SCM_CALIB_API_TOKENS" in detail(r)


def test_openapi_and_docs(tmp_path) -> None:
    with fresh_database("sqlite", tmp_path) as url, api_client(url) as client:
        spec = client.get("/openapi.json").json()
        paths = spec["paths"]
        for path in (
            "/health",
            "/health/ready",
            "/datasets",
            "/datasets/{dataset_id}/series",
            "/presets/{name}",
            "/studies",
            "/studies/{study_id}",
            "/studies/{study_id}/cancel",
            "/studies/{study_id}/stages",
            "/studies/{study_id}/stages/{stage}/samples",
            "/studies/{study_id}/stages/{stage}/samples.csv",
            "/studies/{study_id}/summary",
            "/studies/{study_id}/events",
            "/pooled",
        ):
            assert path in paths, path
        upload = paths["/datasets"]["post"]["requestBody"]["content"]
        assert set(upload) == {"multipart/form-data", "application/json"}
        assert "StudyCreate" in spec["components"]["schemas"]
        docs = client.get("/docs")
        assert docs.status_code == 200 and "swagger" in docs.text.lower()
