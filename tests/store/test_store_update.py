"""Posterior updates (kind "update") through the store and the real orchestrator, on SQLite and
PostgreSQL: the updated population is bit-identical to the in-memory TMCMC started from the
parent's population with the old datasets in the base density; the evidence is the incremental
one with the total alongside; bad requests name their field and store nothing."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

from scm_core.calibration import (
    CaseDefinition,
    PopulationStart,
    StudyModel,
    UpdateLikelihood,
    run_tmcmc,
)
from scm_core.signals import load_log
from services.config import Settings
from services.store import Store
from services.store.models import Study
from services.studies import StudyRequestError, calibration_spec, create_and_start
from services.studies.datasets import load_datasets
from services.studies.kinds.update import update_spec
from worker.orchestrator import ContextCache, execute_batch

ROOT = Path(__file__).resolve().parents[2]
LOGS = [ROOT / "examples" / "wf34_s020.csv", ROOT / "examples" / "wf34_s050.csv"]

#: coarse, short runs (populations are compared bit for bit, not against physics)
CASE = CaseDefinition.from_dict(
    {
        "name": "upd",
        "seed": 11,
        "parameters": {"phi": {"dist": "uniform", "lower": 20.0, "upper": 40.0}},
        "nominal": {"sigma_F": 8.0, "sigma_T": 0.8, "sigma_z": 0.002},
        "simulator": {
            "duration": 6.0,
            "dx": 0.01,
            "dt": 0.04,
            "offset_F": 2.0,
            "offset_T": 2.0,
            "offset_z": 2.0,
        },
        "sampler": {"n_samples": 24, "n_steps": 2, "batch_size": 10},
    }
)


@pytest.fixture
def dataset_ids(store: Store) -> list[int]:
    ids = []
    for log in LOGS:
        raw = log.read_bytes()
        meta = json.loads(log.with_suffix(".json").read_text())
        rec, _ = store.datasets.add(load_log(raw, metadata=meta), raw, meta=meta)
        ids.append(rec.id)
    return ids


def _run(store: Store, study_id: int) -> None:
    """Run every batch in this process until the study ends."""
    cache = ContextCache()
    while store.studies.get(study_id).status == "running":
        study = store.studies.get(study_id)
        keys = [b.key for b in store.batches.list(study_id, study.current_stage)]
        for key in keys:
            execute_batch(store, key, cache, None)


def test_update_is_the_in_memory_update_bit_for_bit(store: Store, dataset_ids) -> None:
    settings = Settings()
    parent_id = create_and_start(
        store, calibration_spec(store, settings, CASE, dataset_ids[:1]), None
    )
    _run(store, parent_id)
    parent = store.studies.get(parent_id)
    assert parent.status == "completed"

    spec = update_spec(store, settings, parent_id, dataset_ids[1:])
    assert spec.kind == "update" and spec.payload == {"update_of": parent_id}
    assert spec.seed == CASE.seed + 1 and spec.n_samples == 24
    study_id = create_and_start(store, spec, None)
    _run(store, study_id)
    done = store.studies.get(study_id)
    assert done.status == "completed", done.error
    assert done.parent_id == parent_id  # the store lists it among the parent's
    assert [s.id for s in store.studies.list(parent=parent_id).items] == [study_id]

    datasets = load_datasets(store, CASE, dataset_ids)
    prior, sampler = CASE.prior(), CASE.tmcmc_settings()
    ref_parent = run_tmcmc(
        StudyModel(CASE, datasets[:1]), prior, 24, CASE.seed, sampler, batch_size=10
    )
    ref = run_tmcmc(
        UpdateLikelihood(StudyModel(CASE, datasets), 1),
        prior,
        24,
        CASE.seed + 1,
        sampler,
        batch_size=7,  # the split does not matter
        start=PopulationStart(
            ref_parent.samples, (ref_parent.final.beta, ref_parent.final.acceptance_rate)
        ),
    )
    got = store.samples.arrays(study_id, done.current_stage)
    assert got.samples.tobytes() == ref.samples.tobytes()
    assert got.log_likelihood.tobytes() == ref.log_likelihood.tobytes()
    assert np.array_equal(got.log_prior, ref.log_prior)  # log prior + log L(old)
    assert done.log_evidence == ref.log_evidence  # log Z(new | old)
    assert done.result == {
        "update_of": parent_id,
        "log_evidence_increment": ref.log_evidence,
        "parent_log_evidence": parent.log_evidence,
        "log_evidence_total": parent.log_evidence + ref.log_evidence,
    }
    assert math.isfinite(done.result["log_evidence_total"])
    assert len(store.stages.list(study_id)) == len(ref.stages)

    # an update of the update: its old data are both logs; nothing new is left to add
    with pytest.raises(StudyRequestError, match=r"dataset_ids: dataset .* already in"):
        update_spec(store, settings, study_id, dataset_ids[:1])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ({"update_of": 999}, "update_of: no study with id 999"),
        ({"dataset_ids": []}, "dataset_ids: at least one dataset is needed"),
        ({"dataset_ids": [999]}, "dataset_ids: no dataset with id 999"),
        ({"seed": -1}, "seed: must be 0 <= seed"),
    ],
)
def test_bad_update_requests_name_the_field(store: Store, dataset_ids, args, message) -> None:
    parent = store.studies.create(calibration_spec(store, Settings(), CASE, dataset_ids[:1]))
    with store.db.write() as s:  # as if it had run (its population is not read here)
        s.execute(sa.update(Study).where(Study.id == parent.id).values(status="completed"))
    before = store.studies.list().total
    kwargs = {"update_of": parent.id, "dataset_ids": dataset_ids[1:], **args}
    with pytest.raises(StudyRequestError, match=message):
        update_spec(
            store,
            Settings(),
            kwargs.pop("update_of"),
            kwargs.pop("dataset_ids"),
            **kwargs,
        )
    assert store.studies.list().total == before


def test_only_a_completed_calibration_can_be_updated(store: Store, dataset_ids) -> None:
    parent = store.studies.create(calibration_spec(store, Settings(), CASE, dataset_ids[:1]))
    with pytest.raises(StudyRequestError, match=r"update_of: study \d+ is queued"):
        update_spec(store, Settings(), parent.id, dataset_ids[1:])
