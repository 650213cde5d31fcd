"""Fixtures of the store's and the stage stores' suites (their ``conftest.py`` import them):
every test using ``store`` or ``db_url`` runs on SQLite (a temporary file) and on a real
PostgreSQL; the toy study and the helpers that run it.

PostgreSQL: a fresh database ``scm_calib_test_<random>`` is created through the maintenance
database at ``$SCM_CALIB_TEST_PG_URL`` (default ``postgresql://postgres@127.0.0.1:5432/postgres``),
migrated once, emptied after each test, and dropped at the end of the session. If PostgreSQL is
not reachable the tests FAIL (they are not skipped): CI guarantees the server.
"""

from __future__ import annotations

import os
import threading
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
import sqlalchemy as sa

from scm_core.inference import JointPrior, TMCMCSettings, Uniform
from scm_core.inference.tmcmc.stage import (
    ChainBatchResult,
    PointEvaluation,
    StagePlan,
    StageState,
    chain_batches,
    evaluate_points,
    initial_samples,
    initial_state,
    plan_stage,
    reduce_stage,
    run_chains,
    stage_status,
)
from scm_core.signals import load_summary
from services.stages import DatabaseStages, planned_stage, reduced_stage
from services.store import BatchKey, BatchOutput, ReduceInput, StageAdvance, Store, StudySpec
from services.store.codec import decode, encode
from services.store.engine import make_engine, normalise_url
from services.store.migrate import upgrade
from services.store.models import Base

PG_ENV = "SCM_CALIB_TEST_PG_URL"
PG_DEFAULT = "postgresql://postgres@127.0.0.1:5432/postgres"
BACKENDS = ["sqlite", "postgresql"]


# ---- PostgreSQL server and databases ---------------------------------------------------------


class PgServer:
    """Creates and drops throw-away databases through the maintenance database."""

    def __init__(self, url: str) -> None:
        self.url = normalise_url(url)
        self.engine = sa.create_engine(self.url, isolation_level="AUTOCOMMIT")
        self.created: list[str] = []

    def check(self) -> None:
        error: Exception | None = None
        try:
            with self.engine.connect() as conn:
                conn.execute(sa.text("SELECT 1"))
        except Exception as exc:  # pragma: no cover - environment problem
            error = exc
        if error is not None:  # pragma: no cover
            exc = error
            pytest.fail(
                f"PostgreSQL is required for tests/store but is not reachable at "
                f"{self.url.render_as_string(hide_password=True)} ({type(exc).__name__}: {exc}). "
                f"Start it (e.g. `pg_ctlcluster --skip-systemctl-redirect $(ls /etc/postgresql) "
                f"main start`) or point {PG_ENV} at a server.",
                pytrace=False,
            )

    def create(self) -> str:
        name = f"scm_calib_test_{uuid.uuid4().hex[:12]}"
        with self.engine.connect() as conn:
            conn.execute(sa.text(f'CREATE DATABASE "{name}"'))
        self.created.append(name)
        return self.url.set(database=name).render_as_string(hide_password=False)

    def drop(self, url: str) -> None:
        name = sa.make_url(url).database
        with self.engine.connect() as conn:
            conn.execute(sa.text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        if name in self.created:
            self.created.remove(name)

    def close(self) -> None:
        for name in list(self.created):
            with self.engine.connect() as conn:
                conn.execute(sa.text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        self.engine.dispose()


@pytest.fixture(scope="session")
def pg_server() -> Iterator[PgServer]:
    server = PgServer(os.environ.get(PG_ENV, PG_DEFAULT))
    server.check()
    yield server
    server.close()


@pytest.fixture(scope="session")
def pg_migrated_url(pg_server: PgServer) -> str:
    """One migrated PostgreSQL database for the session (emptied after each test)."""
    url = pg_server.create()
    upgrade(url)
    return url


def _truncate_pg(url: str) -> None:
    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            tables = ", ".join(t.name for t in Base.metadata.sorted_tables)
            conn.execute(sa.text(f"TRUNCATE {tables} RESTART IDENTITY CASCADE"))
    finally:
        engine.dispose()


@pytest.fixture(params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture
def empty_url(backend: str, tmp_path, request: pytest.FixtureRequest) -> Iterator[str]:
    """A database with no schema at all (fresh per test)."""
    if backend == "sqlite":
        yield f"sqlite:///{tmp_path / 'empty.db'}"
        return
    server: PgServer = request.getfixturevalue("pg_server")
    url = server.create()
    yield url
    server.drop(url)


@pytest.fixture
def db_url(backend: str, tmp_path, request: pytest.FixtureRequest) -> Iterator[str]:
    """A database migrated to head, empty at the start of the test."""
    if backend == "sqlite":
        url = f"sqlite:///{tmp_path / 'store.db'}"
        upgrade(url)
        yield url
        return
    url = request.getfixturevalue("pg_migrated_url")
    _truncate_pg(url)
    yield url
    _truncate_pg(url)


# ---- clock and store -------------------------------------------------------------------------


class FakeClock:
    """A settable clock: ``clock()`` is the time, ``clock.advance(seconds)`` moves it."""

    def __init__(self) -> None:
        self.now = datetime(2030, 1, 1, 12, 0, 0, tzinfo=UTC)

    def __call__(self) -> datetime:
        return self.now

    def advance(self, seconds: float) -> None:
        self.now = self.now + timedelta(seconds=seconds)


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


LEASE_SECONDS = 60.0
MAX_ATTEMPTS = 2


@pytest.fixture
def store(db_url: str, clock: FakeClock) -> Iterator[Store]:
    s = Store.open(db_url, lease_seconds=LEASE_SECONDS, max_attempts=MAX_ATTEMPTS, clock=clock)
    yield s
    s.close()


@pytest.fixture
def open_store(db_url: str, clock: FakeClock) -> Iterator[Callable[[], Store]]:
    """Factory of extra Store objects on the same database (separate engines and sessions)."""
    stores: list[Store] = []

    def make() -> Store:
        s = Store.open(db_url, lease_seconds=LEASE_SECONDS, max_attempts=MAX_ATTEMPTS, clock=clock)
        stores.append(s)
        return s

    yield make
    for s in stores:
        s.close()


# ---- test data -------------------------------------------------------------------------------


def summary_csv(shift: float = 0.0) -> bytes:
    """A per-trial summary SWT dataset as uploaded bytes (different ``shift``, different hash)."""
    rows = [(19 + shift, 5.0, 11), (20 + shift, 5.5, 12), (21 + shift, 6.0, 13)]
    text = "# slip: 0.2\n# W: 315\ntrial,F [N],T [Nm],z [mm]\n"
    text += "".join(f"{i + 1},{f},{t},{z}\n" for i, (f, t, z) in enumerate(rows))
    return text.encode()


@pytest.fixture
def make_dataset() -> Callable[..., tuple]:
    def make(shift: float = 0.0):
        raw = summary_csv(shift)
        return load_summary(raw, name=f"trials {shift}"), raw

    return make


class Toy:
    """A small TMCMC problem: 2 parameters, a Gaussian likelihood with a -inf region, two
    responses; 48 samples in batches of 16 chains."""

    n_samples = 48
    batch_size = 16
    seed = 12345

    def __init__(self) -> None:
        self.prior = JointPrior({"a": Uniform(0.0, 1.0), "b": Uniform(-2.0, 2.0)})
        self.settings = TMCMCSettings(n_steps=2, max_stages=30)

    @staticmethod
    def log_likelihood(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ll = -0.5 * ((X[:, 0] - 0.3) ** 2 + (X[:, 1] - 0.5) ** 2) / 0.05**2
        ll = np.where(X[:, 0] > 0.85, -np.inf, ll)
        responses = np.column_stack([X.sum(axis=1), np.where(X[:, 1] > 1.5, np.nan, X[:, 1])])
        return ll, responses

    def spec(self, dataset_ids=(), name: str = "toy", seed: int | None = None) -> StudySpec:
        return StudySpec(
            name=name,
            case={
                "case": "toy",
                "responses": ["F", "T"],
                "priors": self.prior.to_dict(),
                "sampler": self.settings.to_dict(),
                "simulator": {"duration": 25.0},
            },
            dataset_ids=list(dataset_ids),
            seed=self.seed if seed is None else seed,
            n_samples=self.n_samples,
            kind="calibration",
            batch_size=self.batch_size,
        )

    def batches(self, n: int) -> list[range]:
        return chain_batches(n, self.batch_size)

    def initial_points(self, seed: int) -> np.ndarray:
        return initial_samples(self.prior, self.n_samples, seed)

    @staticmethod
    def output(result, key: BatchKey, chains: range) -> BatchOutput:
        """A TMCMC batch result as the store keeps it."""
        return BatchOutput(key.stage_index, chains.start, chains.stop, encode(result))

    @staticmethod
    def plan(store: Store, study_id: int, stage_index: int) -> StagePlan | None:
        blob = store.stages.plan(study_id, stage_index)
        return None if blob is None else decode(blob, StagePlan)

    @staticmethod
    def state(store: Store, study_id: int, stage_index: int) -> StageState:
        return DatabaseStages(store, study_id).state(stage_index)

    def reduced_state(self, inp: ReduceInput) -> StageState:
        """The stage's TMCMC state from the reducer's input."""
        if inp.stage.stage_index == 0:
            X = self.initial_points(inp.study.seed)
            points = [decode(b, PointEvaluation) for b in inp.results]
            return initial_state(self.prior, X, points, inp.study.seed, self.settings)
        chains = [decode(b, ChainBatchResult) for b in inp.results]
        return reduce_stage(decode(inp.plan, StagePlan), chains)

    def reduce(self, inp: ReduceInput) -> StageAdvance:
        """The orchestrator's reducer: stage state, then the next plan or the end."""
        state = self.reduced_state(inp)
        status = stage_status(state, self.settings)
        if status is None:
            plan = plan_stage(state, self.prior, self.settings)
            return StageAdvance(
                reduced_stage(state), planned_stage(plan), self.batches(plan.n_chains)
            )
        final = "completed" if status == "completed" else "stalled"
        return StageAdvance(reduced_stage(state), final_status=final)


@pytest.fixture
def toy() -> Toy:
    return Toy()


# ---- running the toy study ---------------------------------------------------------------------


def in_memory_run(toy):
    X = initial_samples(toy.prior, toy.n_samples, toy.seed)
    evals = [evaluate_points(X[r.start : r.stop], toy.log_likelihood) for r in toy.batches(len(X))]
    state = initial_state(toy.prior, X, evals, toy.seed, toy.settings)
    states = [state]
    while stage_status(state, toy.settings) is None:
        plan = plan_stage(state, toy.prior, toy.settings)
        results = [run_chains(plan, r, toy.log_likelihood) for r in toy.batches(plan.n_chains)]
        state = reduce_stage(plan, results)
        states.append(state)
    return states


def work_one(store: Store, toy, worker: str) -> bool:
    """Lease one batch, run it, store it, advance the stage if it was the last. False if idle."""
    lease = store.batches.lease(worker)
    if lease is None:
        return False
    key = lease.key
    if key.stage_index == 0:
        study = store.studies.get(key.study_id)
        X = toy.initial_points(study.seed)[lease.chain_start : lease.chain_stop]
        result = evaluate_points(X, toy.log_likelihood)
    else:
        plan = toy.plan(store, key.study_id, key.stage_index)
        result = run_chains(plan, lease.chains, toy.log_likelihood)
    assert store.batches.heartbeat(lease)
    outcome = store.batches.complete(key, toy.output(result, key, lease.chains))
    assert outcome.status == "stored"
    if outcome.stage_complete:
        adv = store.stages.advance(key.study_id, key.stage_index, toy.reduce)
        assert adv.status == "advanced"
    return True


@contextmanager
def transaction_held_open(reset) -> Iterator[Callable[[], None]]:
    """A use of ``reset`` (:class:`services.store.fault_reset.FaultReset`) held open by another
    thread (a transaction that does not end) until the returned function is called or the
    block ends."""
    held, release = threading.Event(), threading.Event()

    def hold() -> None:
        with reset.use():
            held.set()
            release.wait(30)

    thread = threading.Thread(target=hold)
    thread.start()
    held.wait(10)

    def end() -> None:
        release.set()
        thread.join()

    try:
        yield end
    finally:
        end()
