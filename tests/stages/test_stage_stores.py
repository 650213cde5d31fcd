"""One suite for the one stage-storage interface (:class:`services.stages.StageStore`), run on
its two implementations and both databases: a results folder (:class:`FolderStages`, written
by the CLI's driver ``run_tmcmc`` stage by stage), SQLite and PostgreSQL
(:class:`DatabaseStages`, written by the service's exactly-once stage advance with leased
batches). The same toy study (two parameters, a Gaussian likelihood with a -inf region, 48
samples in batches of 16) is run into each; every store must give back the in-memory run's
stages bit for bit, resume it to the same posterior and export it the same way."""

from __future__ import annotations

import math

import numpy as np
import pytest
from store_fixtures import in_memory_run, work_one

from scm_core.inference import Resume, StageHooks, run_tmcmc
from services.stages import (
    DatabaseStages,
    FolderStages,
    StageStore,
    StageStoreError,
    run_population,
    stage_states,
)
from services.store import Store

STORES = ["folder", "sqlite", "postgresql"]


def _run_tmcmc(toy, **kw):
    """The toy study through the CLI's driver (in memory, batches of 16 chains)."""
    return run_tmcmc(
        toy.log_likelihood,
        toy.prior,
        toy.n_samples,
        toy.seed,
        toy.settings,
        batch_size=toy.batch_size,
        **kw,
    )


def _run_into_folder(toy, out) -> FolderStages:
    """The CLI's way: run_tmcmc in memory, each finished stage saved as it ends."""
    stages = FolderStages(out)
    _run_tmcmc(toy, hooks=StageHooks(on_stage=lambda s: stages.save(s, 0.5 + s.stage)))
    return stages


def _run_into_database(toy, store: Store) -> DatabaseStages:
    """The service's way: a stored study, its batches leased, run and completed one by one,
    each stage advanced exactly once when its last batch is in."""
    study = store.studies.create(toy.spec())
    store.studies.start(study.id, toy.batches(toy.n_samples))
    while work_one(store, toy, "w1"):
        pass
    assert store.studies.get(study.id).status == "completed"
    return DatabaseStages(store, study.id)


@pytest.fixture
def backend(request: pytest.FixtureRequest) -> str:
    """Which store the test runs on (overrides the store suite's database-only fixture)."""
    return request.param


@pytest.fixture
def stages(backend: str, toy, tmp_path, request: pytest.FixtureRequest) -> StageStore:
    """The toy study's stages, kept in the store ``backend`` names."""
    if backend == "folder":
        return _run_into_folder(toy, tmp_path / "results")
    return _run_into_database(toy, request.getfixturevalue("store"))


@pytest.fixture
def expected(toy):
    """The toy study's stages in memory (no store): the reference."""
    return in_memory_run(toy)


#: a test run on every store
on_every_store = pytest.mark.parametrize("backend", STORES, indirect=True)


@on_every_store
def test_every_store_is_a_stage_store(stages: StageStore) -> None:
    assert isinstance(stages, StageStore)


@on_every_store
def test_a_store_gives_back_every_stage_bit_for_bit(stages: StageStore, expected) -> None:
    assert len(expected) >= 4  # a run of several tempering stages
    assert stages.count() == len(expected)
    for i, exp in enumerate(expected):
        got = stages.state(i)
        assert got.equals(exp), f"stage {i} differs"
        assert got.samples.tobytes() == exp.samples.tobytes()
        assert got.responses.tobytes() == exp.responses.tobytes()  # NaN responses kept
    assert stages.state(-1).equals(expected[-1])
    assert stages.state(-len(expected)).equals(expected[0])
    assert np.isinf(stages.state(0).log_likelihood).any()  # -inf survived the store


@on_every_store
def test_a_store_gives_every_stage_row(stages: StageStore, expected) -> None:
    rows = stages.rows()
    assert [r.exponent for r in rows] == [float(s.exponent) for s in expected]
    for row, exp in zip(rows, expected, strict=True):
        for got, want in (
            (row.acceptance_rate, exp.acceptance_rate),
            (row.log_evidence, exp.log_evidence),
        ):
            assert got == want or (math.isnan(got) and math.isnan(want))
    assert rows[-1].exponent == 1.0


@on_every_store
def test_a_store_refuses_a_stage_it_does_not_hold(stages: StageStore) -> None:
    n = stages.count()
    for index in (n, n + 3, -n - 1):
        with pytest.raises(StageStoreError, match=f"no finished stage {index} \\({n} finished"):
            stages.state(index)


@on_every_store
def test_a_run_resumes_from_any_stored_stage_to_the_same_posterior(
    stages: StageStore, expected, toy
) -> None:
    for k in (1, 2, stages.count() - 1):
        resumed = _run_tmcmc(toy, start=Resume(stage_states(stages, k)))
        assert len(resumed.stages) == len(expected)
        assert resumed.final.equals(expected[-1]), f"resumed after stage {k - 1}"
        assert resumed.log_evidence == expected[-1].log_evidence


@on_every_store
def test_a_store_exports_its_run_the_same_way(stages: StageStore, expected) -> None:
    run = run_population(stages)
    assert run.samples.tobytes() == expected[-1].samples.tobytes()
    assert run.log_likelihood.tobytes() == expected[-1].log_likelihood.tobytes()
    assert run.log_prior.tobytes() == expected[-1].log_prior.tobytes()
    assert run.prior_samples.tobytes() == expected[0].samples.tobytes()
    assert [r.exponent for r in run.stages] == [float(s.exponent) for s in expected]


@on_every_store
def test_an_empty_store_holds_no_stage(backend: str, tmp_path, request) -> None:
    empty = (
        FolderStages(tmp_path / "nothing")
        if backend == "folder"
        else DatabaseStages(request.getfixturevalue("store"), 12345)
    )
    assert empty.count() == 0 and empty.rows() == []
    with pytest.raises(StageStoreError, match="no finished stage -1"):
        empty.state(-1)
    with pytest.raises(StageStoreError, match="no tempering stage has finished"):
        run_population(empty)


def test_a_folder_saves_its_stages_in_order(toy, expected, tmp_path) -> None:
    stages = FolderStages(tmp_path)
    with pytest.raises(StageStoreError, match="stage 1 saved after 0 stages"):
        stages.save(expected[1], 1.0)
    for s in expected[:2]:
        stages.save(s, 2.5)
    assert stages.count() == 2 and stages.saved(1)[1] == 2.5
    with pytest.raises(StageStoreError, match="stage 1 saved after 2 stages"):
        stages.save(expected[1], 1.0)
    stages.path(1).write_text("{", encoding="utf-8")  # a damaged file is named
    with pytest.raises(StageStoreError, match=r"stage_001\.json: unreadable checkpoint"):
        stages.state(1)
