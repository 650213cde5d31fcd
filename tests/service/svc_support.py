"""Real PostgreSQL, Redis and Celery worker processes for the distributed-mode tests (helpers
and fixtures; the fixtures are registered by conftest.py)."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path

import psycopg
import pytest
import redis

from scm_core.calibration import load_case
from scm_core.signals import load_log
from services.store import Store
from services.store.migrate import upgrade

HERE = Path(__file__).parent
ROOT = HERE.parent.parent
CASE_FILE = HERE / "data" / "svc_case.toml"
LOG_FILE = ROOT / "examples" / "wf34_s020.csv"
LOG_FILE2 = ROOT / "examples" / "wf34_s050.csv"  # the new test of an update
PREDICTION = {"draws": 24, "seed": 3}
PG_ADMIN = "postgresql://postgres@127.0.0.1:5432/postgres"
LEASE_SECONDS = 4.0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def pg_url():
    """A fresh PostgreSQL database at the schema's head revision, dropped afterwards."""
    name = f"scm_calib_svc_{uuid.uuid4().hex[:10]}"
    try:
        with psycopg.connect(PG_ADMIN, autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
    except psycopg.OperationalError as exc:  # CI starts PostgreSQL: a skip would hide a failure
        pytest.fail(f"PostgreSQL at 127.0.0.1:5432 is needed for this test: {exc}")
    url = f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"
    upgrade(url)
    yield url
    with psycopg.connect(PG_ADMIN, autocommit=True) as conn:
        conn.execute(
            "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = %s", (name,)
        )
        conn.execute(f'DROP DATABASE IF EXISTS "{name}"')


class RedisServer:
    """A throwaway redis-server on its own port (no persistence): can be killed and restarted."""

    def __init__(self) -> None:
        self.port = free_port()
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self) -> None:
        exe = shutil.which("redis-server")
        if exe is None:
            pytest.fail("redis-server is needed for this test")
        self.proc = subprocess.Popen(
            [
                exe,
                "--port",
                str(self.port),
                "--bind",
                "127.0.0.1",
                "--save",
                "",
                "--appendonly",
                "no",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        client = redis.Redis(port=self.port)
        for _ in range(100):
            try:
                if client.ping():
                    return
            except redis.ConnectionError:
                time.sleep(0.05)
        pytest.fail("throwaway redis-server did not start")

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc = None


@pytest.fixture
def redis_server():
    server = RedisServer()
    server.start()
    yield server
    server.stop()


def service_env(db_url: str, broker_url: str) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        SCM_CALIB_DATABASE_URL=db_url,
        SCM_CALIB_BROKER_URL=broker_url,
        SCM_CALIB_LEASE_SECONDS=str(LEASE_SECONDS),
        SCM_CALIB_MAX_ATTEMPTS="5",
        NUMBA_NUM_THREADS="1",
        PYTHONUNBUFFERED="1",
    )
    return env


class Processes:
    """Child processes of a test (workers, reaper, API), all killed at the end."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.procs: list[subprocess.Popen] = []

    def start(self, name: str, args: list[str], env: dict[str, str]) -> subprocess.Popen:
        log = open(self.tmp / f"{name}.log", "w")  # noqa: SIM115 (closed with the process)
        proc = subprocess.Popen(
            [sys.executable, "-m", "services.cli", *args],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            cwd=ROOT,
        )
        self.procs.append(proc)
        return proc

    def worker(self, env: dict[str, str], name: str) -> subprocess.Popen:
        return self.start(name, ["worker", "--pool", "solo", "--concurrency", "1"], env)

    def reaper(self, env: dict[str, str]) -> subprocess.Popen:
        return self.start("reaper", ["reaper", "--interval", "1"], env)

    def logs(self) -> str:
        return "\n".join(
            f"--- {p.name}\n{p.read_text()[-3000:]}" for p in sorted(self.tmp.glob("*.log"))
        )

    def stop_all(self) -> None:
        """SIGTERM (a server stops its local pool), then SIGKILL what is left after 10 s."""
        for p in self.procs:
            if p.poll() is None:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=30)


@pytest.fixture
def processes(tmp_path):
    procs = Processes(tmp_path)
    yield procs
    procs.stop_all()


@pytest.fixture(scope="session")
def svc_case():
    return load_case(CASE_FILE)


def add_example_dataset(store: Store, case) -> int:
    raw = LOG_FILE.read_bytes()
    meta = json.loads(LOG_FILE.with_suffix(".json").read_text())
    ds = load_log(raw, metadata=meta, offset=case.data.offset)
    rec, _ = store.datasets.add(ds, raw, meta=meta, filename=LOG_FILE.name)
    return rec.id


def _cli(*args: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr


def _final_state(out: Path):
    from services.cli.results import results_stages

    summary = json.loads((out / "summary.json").read_text())
    with results_stages(out, summary) as stages:
        return stages.state(-1)


@pytest.fixture(scope="session")
def reference_run(tmp_path_factory) -> Path:
    """The results folder of ``scm-calib calibrate`` on the service tests' case."""
    out = tmp_path_factory.mktemp("calibrate")
    _cli("calibrate", str(CASE_FILE), "--out", str(out), "--no-plots", "--quiet")
    return out


@pytest.fixture(scope="session")
def reference_samples(reference_run):
    """Final stage of the same study run by ``scm-calib calibrate`` (bit-exact checkpoint)."""
    return _final_state(reference_run)


@pytest.fixture(scope="session")
def reference_update(tmp_path_factory, reference_run):
    """Final stage of ``scm-calib calibrate --update-of`` the reference with the slip 0.5 log."""
    out = tmp_path_factory.mktemp("update")
    _cli(
        *("calibrate", "--update-of", str(reference_run), "--data", str(LOG_FILE2)),
        *("--out", str(out), "--no-plots", "--quiet"),
    )
    return _final_state(out)


@pytest.fixture(scope="session")
def reference_prediction(tmp_path_factory, reference_run) -> dict:
    """``scm-calib predict`` of the reference on the slip 0.5 log (predictions.json)."""
    out = tmp_path_factory.mktemp("predict")
    _cli(
        *("predict", str(reference_run), "--data", str(LOG_FILE2)),
        *("--draws", str(PREDICTION["draws"]), "--seed", str(PREDICTION["seed"])),
        *("--out", str(out), "--no-plots"),
    )
    doc = json.loads((out / "predictions.json").read_text())
    # the CLI's file also lists each draw's values (for ArviZ's posterior_predictive); the
    # service keeps those in the prediction's stage samples, its result has the bands
    for d in doc["datasets"]:
        for r in d["responses"].values():
            r.pop("draws", None)
    return doc
