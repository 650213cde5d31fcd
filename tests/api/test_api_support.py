"""Helpers shared by the API tests (imported by the test_api_* modules; no tests here).

Databases are real: a temporary SQLite file, or a fresh PostgreSQL database made through the
``postgres`` maintenance database at ``$SCM_CALIB_TEST_PG_URL`` (default
``postgresql://postgres@127.0.0.1:5432/postgres``) and dropped afterwards. When PostgreSQL is not
reachable the tests fail; they are never skipped.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import uuid
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest
import sqlalchemy as sa

from services.api import create_app
from services.config import Settings
from services.store import Store
from services.store.engine import make_engine, normalise_url
from services.store.migrate import upgrade
from worker.orchestrator import ContextCache, execute_batch

with warnings.catch_warnings():  # starlette warns that httpx should become httpx2
    warnings.simplefilter("ignore", UserWarning)
    from fastapi.testclient import TestClient

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
LOG = EXAMPLES / "wf34_s020.csv"
LOG2 = EXAMPLES / "wf34_s050.csv"
TOKEN = "api-test-token-3f1c"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
PG_ENV = "SCM_CALIB_TEST_PG_URL"
PG_DEFAULT = "postgresql://postgres@127.0.0.1:5432/postgres"
BACKENDS = ["sqlite", "postgresql"]
TABLES = (
    "datasets",
    "dataset_uploads",
    "study_datasets",
    "studies",
    "stages",
    "work_batches",
    "samples",
    "events",
)


# ---------------------------------------------------------------------------- databases


class PgAdmin:
    """Creates and drops throw-away PostgreSQL databases."""

    def __init__(self) -> None:
        self.url = normalise_url(os.environ.get(PG_ENV, PG_DEFAULT))
        self.engine = sa.create_engine(self.url, isolation_level="AUTOCOMMIT")
        try:
            with self.engine.connect() as conn:
                conn.execute(sa.text("SELECT 1"))
        except Exception as exc:
            self.engine.dispose()
            pytest.fail(
                f"PostgreSQL is required by tests/api but is not reachable at "
                f"{self.url.render_as_string(hide_password=True)} ({type(exc).__name__}: {exc}); "
                f"start it or point {PG_ENV} at a server",
                pytrace=False,
            )

    def create(self) -> str:
        name = f"scm_calib_api_{uuid.uuid4().hex[:12]}"
        with self.engine.connect() as conn:
            conn.execute(sa.text(f'CREATE DATABASE "{name}"'))
        return self.url.set(database=name).render_as_string(hide_password=False)

    def drop(self, url: str) -> None:
        name = sa.make_url(url).database
        with self.engine.connect() as conn:
            conn.execute(sa.text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))

    def close(self) -> None:
        self.engine.dispose()


@contextmanager
def fresh_database(backend: str, directory: Path, migrate: bool = True) -> Iterator[str]:
    """A new, empty database (at the head revision unless ``migrate=False``)."""
    if backend == "sqlite":
        url = f"sqlite:///{directory / f'api-{uuid.uuid4().hex[:8]}.db'}"
        if migrate:
            upgrade(url)
        yield url
        return
    admin = PgAdmin()
    url = admin.create()
    try:
        if migrate:
            upgrade(url)
        yield url
    finally:
        admin.drop(url)
        admin.close()


def row_counts(url: str) -> dict[str, int]:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            count = "SELECT count(*) FROM {}"
            return {t: int(conn.execute(sa.text(count.format(t))).scalar()) for t in TABLES}
    finally:
        engine.dispose()


# ---------------------------------------------------------------------------- app


def settings_for(url: str, **overrides: Any) -> Settings:
    values: dict[str, Any] = {
        "database_url": url,
        "broker_url": None,
        "api_tokens": [TOKEN],
        "read_requires_token": False,
        "worker_concurrency": 2,
        "lease_seconds": 60.0,
        "max_attempts": 3,
    }
    values.update(overrides)
    return Settings(**values)


@contextmanager
def api_client(
    url: str, *, start_local_runtime: bool = False, **settings: Any
) -> Iterator[TestClient]:
    """A TestClient of ``create_app`` on ``url`` (lifespan run: store opened, runtime started
    when asked)."""
    app = create_app(settings_for(url, **settings), start_local_runtime=start_local_runtime)
    with TestClient(app) as client:
        yield client


def upload_file(client: TestClient, path: Path = LOG, headers: dict | None = None, **form: Any):
    """POST /datasets of a log with its JSON sidecar as metadata."""
    data = dict(form)
    sidecar = path.with_suffix(".json")
    if "metadata" not in data and sidecar.is_file():
        data["metadata"] = sidecar.read_text()
    files = {"file": (path.name, path.read_bytes(), "text/csv")}
    headers = AUTH if headers is None else headers
    return client.post("/datasets", files=files, data=data, headers=headers)


def summary_doc(shift: float = 0.0, name: str | None = None) -> dict[str, Any]:
    """A summary dataset (JSON form); another ``shift`` gives other content."""
    return {
        "name": name or f"summary {shift:g}",
        "conditions": {"W": 315.0, "slip": 0.2},
        "responses": {
            "F": {"mean": 50.0 + shift, "sd": 2.0, "unit": "N"},
            "T": {"mean": 10.0, "sd": 0.5, "unit": "Nm"},
            "z": {"mean": 19.0, "sd": 1.0, "unit": "mm"},
        },
        "n_trials": 3,
    }


def tiny_case(seed: int = 5, params: tuple[str, ...] = ("phi", "n"), **sampler: Any) -> dict:
    """A case that completes in a few stages of very short, coarse simulations."""
    priors = {
        "phi": {"dist": "uniform", "lower": 20.0, "upper": 35.0, "unit": "deg"},
        "n": {"dist": "uniform", "lower": 0.9, "upper": 1.3, "unit": "-"},
        "J": {"dist": "uniform", "lower": 0.001, "upper": 0.02, "unit": "m/s"},
    }
    return {
        "name": "tiny",
        "seed": seed,
        "likelihood": "gaussian",
        "parameters": {p: priors[p] for p in params},
        "nominal": {"k_c": 0.0, "sigma_F": 30.0, "sigma_T": 3.0, "sigma_z": 0.005},
        "simulator": {
            "duration": 8.0,
            "dx": 0.01,
            "dt": 0.04,
            "offset_F": 3.0,
            "offset_T": 3.0,
            "offset_z": 3.0,
        },
        "sampler": {"n_samples": 20, "moves": "leader", "max_stages": 8, **sampler},
    }


def run_inline(url: str, study_id: int, timeout: float = 300.0) -> str:
    """Run a study's work batches in this process through the real orchestrator (claim, run,
    store, advance) until it ends; returns its final status."""
    store = Store.open(url)
    cache = ContextCache()
    deadline = time.monotonic() + timeout
    try:
        while True:
            study = store.studies.get(study_id)
            if study.status != "running" or time.monotonic() > deadline:
                return study.status
            batches = store.batches.list(study_id, study.current_stage)
            for b in batches:
                if b.status == "pending":
                    execute_batch(store, b.key, cache, None)
    finally:
        store.close()


def wait_ended(get: Any, path: str, timeout: float = 300.0, every: float = 0.3) -> dict:
    """Poll ``get(path)`` (a TestClient's or an httpx client's ``get``) until the study there
    is no longer queued or running; its JSON. Fails the test after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        body = get(path).json()
        if body["status"] not in ("queued", "running"):
            return body
        time.sleep(every)
    pytest.fail(f"{path} did not finish within {timeout:g} s")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def detail(response) -> str:
    """The error message, checking the ``{"detail": "<str>"}`` form."""
    body = response.json()
    assert set(body) >= {"detail"} and isinstance(body["detail"], str), body
    return body["detail"]


def dumps(doc: Any) -> str:
    return json.dumps(doc)


# ---------------------------------------------------------------------------- a real server

#: seconds ``scm-calib serve`` has to get ready (database migrated, local pool warmed up)
SERVE_START_TIMEOUT = 60.0


def serve_env(tmp: Path, **extra: str) -> dict[str, str]:
    """The environment of a ``scm-calib`` subprocess: none of the caller's ``SCM_CALIB_*``
    settings, data directory (SQLite database) in ``tmp``, the test token, one numba thread."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SCM_CALIB_")}
    env.update(
        SCM_CALIB_DATA_DIR=str(tmp / "data"),
        SCM_CALIB_API_TOKENS=TOKEN,
        NUMBA_NUM_THREADS="1",
        PYTHONUNBUFFERED="1",
        **extra,
    )
    return env


@contextmanager
def serving(
    tmp: Path, env: dict[str, str] | None = None, workers: int = 2
) -> Iterator[tuple[str, dict[str, str], Path, int]]:
    """A fresh embedded ``scm-calib serve`` subprocess on a free port of 127.0.0.1 (data
    directory in ``tmp``, ``workers`` local workers, its log in ``tmp/serve.log``), once ready
    (database writable and the local pool warmed up): yields (base URL, env, tmp, pid). Stopped
    with SIGINT on exit, which it must answer with exit code 0 within 30 s."""
    env = serve_env(tmp) if env is None else env
    port = free_port()
    log_path = tmp / "serve.log"
    log = open(log_path, "w")  # noqa: SIM115 (closed below)
    command = ["serve", "--port", str(port), "--workers", str(workers)]
    proc = subprocess.Popen(
        [sys.executable, "-m", "services.cli", *command],
        env=env,
        cwd=tmp,  # no .env of the checkout is read
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + SERVE_START_TIMEOUT
    try:
        while True:
            try:
                if httpx.get(base + "/health/ready", timeout=2.0).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"serve did not come up:\n{log_path.read_text()}")
            time.sleep(0.2)
        yield base, env, tmp, proc.pid
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                pytest.fail("serve did not stop within 30 s of SIGINT")
        log.close()
    assert proc.returncode == 0, log_path.read_text()


def svg_text(svg: str) -> str:
    """The words an SVG figure shows (matplotlib's text kept as text), its lines joined by single
    spaces: a title wrapped over two lines reads as one."""
    root = ET.fromstring(svg.encode())
    words = (t for el in root.iter() if el.tag.endswith("}text") for t in el.itertext())
    return " ".join(" ".join(words).split())
