"""Morris sensitivity studies through the store and the real orchestrator, on SQLite and
PostgreSQL: the stored statistics are bit-identical to ``run_sensitivity`` in memory, a second
delivery of a batch changes nothing, the design points and their F, T, z are the stage's
samples, and bad requests name their field and store nothing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from scm_core.calibration import CaseDefinition, MorrisSettings, run_sensitivity
from scm_core.signals import load_log
from services.config import Settings
from services.store import Store
from services.studies import StudyRequestError, start_study, work_batches
from services.studies.datasets import load_datasets
from services.studies.kinds.sensitivity import sensitivity_spec
from worker.orchestrator import ContextCache, execute_batch

ROOT = Path(__file__).resolve().parents[2]
LOG = ROOT / "examples" / "wf34_s020.csv"

#: coarse, short runs (the statistics are compared bit for bit, not against physics)
CASE = CaseDefinition.from_dict(
    {
        "name": "screen",
        "parameters": {"phi": {"dist": "uniform", "lower": 20.0, "upper": 35.0}},
        "nominal": {"sigma_F": 5.0, "sigma_T": 0.5, "sigma_z": 0.001},
        "simulator": {
            "duration": 8.0,
            "dx": 0.01,
            "dt": 0.04,
            "offset_F": 3.0,
            "offset_T": 3.0,
            "offset_z": 3.0,
        },
    }
)


@pytest.fixture
def dataset_id(store: Store) -> int:
    raw = LOG.read_bytes()
    meta = json.loads(LOG.with_suffix(".json").read_text())
    rec, _ = store.datasets.add(load_log(raw, metadata=meta), raw, meta=meta)
    return rec.id


def test_morris_study_matches_run_sensitivity(store: Store, dataset_id: int) -> None:
    morris = MorrisSettings(r=3, levels=4, seed=9)
    spec = sensitivity_spec(store, Settings(), CASE, dataset_id, morris, batch_size=4)
    assert spec.kind == "sensitivity" and spec.n_samples == 3 * 7
    # phi is calibrated in the case: its prior bounds are the factor's; the rest are defaults
    assert spec.payload["design"]["bounds"]["phi"] == [20.0, 35.0]
    assert spec.payload["design"]["bounds"]["k_star"] == [1e6, 1e8]
    study = store.studies.create(spec)
    start_study(store, study.id, None)
    cache = ContextCache()
    keys = [b.key for b in store.batches.list(study.id, 0)]
    assert len(keys) == len(work_batches(21, 4)) == 7  # 4 points, then fewer
    outcomes = [execute_batch(store, k, cache, None) for k in keys]
    assert outcomes == ["stored"] * 7

    done = store.studies.get(study.id)
    assert done.status == "completed" and done.kind == "sensitivity"
    assert done.model_runs == 21

    datasets = load_datasets(store, CASE, [dataset_id])
    ref = run_sensitivity(datasets[0], CASE, morris)
    assert done.result == json.loads(json.dumps(ref.to_dict()))  # bit-identical statistics
    a = store.samples.arrays(study.id, 0)
    assert np.array_equal(a.samples, ref.points)
    assert np.array_equal(a.responses, ref.outputs, equal_nan=True)
    assert np.isnan(a.log_likelihood).all() and np.isnan(a.log_prior).all()

    # driving torque and sinkage are positive where a run succeeded (drawbar pull may be
    # negative: on soft soils the motion resistance exceeds the thrust at slip 0.2)
    ok = np.all(np.isfinite(a.responses), axis=1)
    assert ok.sum() >= 15 and np.all(a.responses[ok, 1:3] > 0)
    assert np.all(a.responses[ok, 3] == 0.0)  # driven straight: no lateral force
    # why the others failed, one reason per failed run
    assert sum(done.result["failed_runs_by"].values()) == done.result["n_failed_runs"]
    # the stage keeps them as a calibration's stages do (StageCounts' failed_by)
    (stage,) = store.stages.list(study.id)
    assert stage.meta["failed_by"] == done.result["failed_runs_by"]

    # a second delivery of a batch changes nothing
    before = store.studies.get(study.id)
    lease = store.batches.claim(keys[0], "late-worker")
    assert lease is None  # done: not leased again
    assert store.studies.get(study.id) == before

    assert [s.id for s in store.studies.list(kind="sensitivity").items] == [study.id]
    assert store.studies.list(kind="calibration").total == 0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"dataset_id": 999}, "dataset_id: no dataset with id 999"),
        ({"bounds": {"c": (10.0, 5.0)}}, "bounds.c: need finite lower < upper"),
        ({"bounds": {"k_c": (0.0, 1.0)}}, "bounds: ['k_c'], which are not screened"),
        ({"levels": 5}, "levels: must be an even integer"),
        ({"r": 1}, "r: need at least 2 trajectories"),
    ],
)
def test_bad_sensitivity_requests_name_the_field(
    store: Store, dataset_id: int, kwargs: dict, message: str
) -> None:
    args = {"dataset_id": dataset_id, **kwargs}
    with pytest.raises(StudyRequestError) as info:
        sensitivity_spec(store, Settings(), CASE, args.pop("dataset_id"), MorrisSettings(**args))
    assert message in str(info.value)
    assert store.studies.list().total == 0


def test_unbuildable_configuration_is_refused(store: Store, dataset_id: int) -> None:
    """A factor box whose centre the simulator refuses (phi = 100 deg) is refused, naming the
    factor, before anything is stored."""
    with pytest.raises(StudyRequestError, match=r"bounds.phi: invalid simulator .* less than 90"):
        morris = MorrisSettings(r=2, bounds={"phi": (80.0, 120.0)})
        sensitivity_spec(store, Settings(), CASE, dataset_id, morris)
    assert store.studies.list().total == 0


def test_a_screening_says_why_its_runs_failed(store: Store, dataset_id: int) -> None:
    """A factor box of soils too soft for the wheel's load: the wheel sinks beyond the
    bottoming-out depth (the paper wheel at 315 N needs k* of order 1e6 to stay within 0.1 m),
    so every run fails, and the result says so by reason."""
    (dataset,) = load_datasets(store, CASE, [dataset_id])
    morris = MorrisSettings(r=2, levels=4, seed=1, bounds={"k_star": (1.0e3, 3.0e3)})
    result = run_sensitivity(dataset, CASE, morris).to_dict()
    n = result["n_runs"]
    assert n == 2 * (len(result["factors"]) + 1)
    assert result["n_failed_runs"] == n
    assert result["failed_runs_by"] == {"bottomed_out": n}
