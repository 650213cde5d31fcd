"""Health and readiness, token policy for reads, OpenAPI."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from test_api_support import (
    AUTH,
    BACKENDS,
    api_client,
    detail,
    free_port,
    fresh_database,
    settings_for,
    summary_doc,
)

from services.api import create_app
from services.store import Store
from services.store.migrate import downgrade, head_revision, upgrade


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


def test_ready_refuses_a_read_only_database_and_hides_paths(tmp_path) -> None:
    """A SQLite file opened read-only (as a read-only mount or a wrong owner would leave it;
    the tests run as root, for whom file modes do not count) is not ready, with one line
    saying why; the database is named only to callers with a token."""
    with fresh_database("sqlite", tmp_path) as url:
        with api_client(url) as client:
            body = client.get("/health/ready").json()
            assert str(tmp_path) not in str(body)  # no path without a token
            expected = f"at revision {head_revision()}, writable"
            assert body["checks"]["database"]["detail"] == expected
            body = client.get("/health/ready", headers=AUTH).json()
            assert str(tmp_path) in body["checks"]["database"]["detail"]
        path = url.removeprefix("sqlite:///")
        ro = Store.open(f"sqlite:///file:{path}?mode=ro&uri=true")
        try:
            app = create_app(settings_for(url), store=ro, start_local_runtime=False)
            with TestClient(app) as client:
                r = client.get("/health/ready")
                assert r.status_code == 503
                line = r.json()["detail"]
                assert line == "database: database does not take writes (OperationalError)"
                r = client.get("/health/ready", headers=AUTH)
                assert "attempt to write a readonly database" in r.json()["detail"]
                assert "\n" not in r.json()["detail"]
        finally:
            ro.close()


def test_ready_follows_the_local_pool(tmp_path) -> None:
    """Embedded with its pool: not ready until the processes are warmed up, not ready while a
    killed one is replaced, ready again after."""
    import os
    import signal
    import time

    def wait_ready(client, want: int, timeout: float = 60.0) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            r = client.get("/health/ready")
            if r.status_code == want:
                return r.json()
            time.sleep(0.02)
        raise AssertionError(f"readiness never {want}: {r.text}")

    with (
        fresh_database("sqlite", tmp_path) as url,
        api_client(url, start_local_runtime=True, worker_concurrency=2) as client,
    ):
        body = wait_ready(client, 200)
        assert body["checks"]["pool"]["detail"] == "2 pool processes, 0 busy"
        runtime = client.app.state.runtime
        pids = runtime.pids()
        for pid in pids:
            os.kill(pid, signal.SIGKILL)
        body = wait_ready(client, 503, timeout=10.0)
        assert body["detail"].startswith("pool: ") and "of 2 pool processes up" in body["detail"]
        wait_ready(client, 200)
        assert set(runtime.pids()).isdisjoint(pids)


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


def test_live_fails_when_the_connections_cannot_be_renewed(tmp_path, monkeypatch) -> None:
    """Issue 73: /health/live answers 503 (restart me) when a renewal of the database
    connections after a storage fault waits for a transaction that never ends, and 200 again
    once it ends; a database that is merely down is no reason (readiness says that)."""
    import threading

    from store_fixtures import transaction_held_open

    from services.api.routes import health

    monkeypatch.setattr(health, "STUCK_RENEWAL_S", 0.3)
    with fresh_database("sqlite", tmp_path) as url, api_client(url) as client:
        r = client.get("/health/live")
        assert r.status_code == 200 and r.json()["status"] == "live", r.text
        reset = client.app.state.store.db.fault_reset
        with transaction_held_open(reset) as end:
            reset.fault()
            threading.Event().wait(0.5)
            r = client.get("/health/live")
            assert r.status_code == 503, r.text
            assert r.json()["status"] == "not live"
            assert "restart the server" in r.json()["detail"]
            end()
        client.get("/studies")  # the next transaction renews the connections
        r = client.get("/health/live")
        assert r.status_code == 200, r.text
        assert "renewed 1 time(s)" in r.json()["checks"]["database"]["detail"]
