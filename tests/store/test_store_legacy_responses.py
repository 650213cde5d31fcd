"""Studies stored before the lateral force Fy was declared (issue 70) kept three responses per
dataset (F, T, z) in their sample rows, stage plans and batch results. They still load and go
on, on SQLite and PostgreSQL: read with Fy NaN (``scm_core.signals.responses.widened``), a
calibration stopped half-way (its plans, batch results and populations old) continues to the
same samples bit for bit as one that never stopped, with the delayed-acceptance surrogate on;
an update of such a study is the in-memory update bit for bit; a stored prediction reads back
as its result. The stored forms are made old here by cutting the fourth response
of each dataset out of what this code stored: exactly the bytes the code before wrote (the
responses are appended, never reordered)."""

from __future__ import annotations

import json
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
from scm_core.inference.tmcmc.stage import ChainBatchResult, StagePlan
from scm_core.signals import load_log
from scm_core.signals.responses import N_FIRST, N_RESPONSES
from services.api.views import named_responses
from services.config import Settings
from services.stages import DatabaseStages
from services.store import Store
from services.store.codec import decode, encode, f64_bytes
from services.store.models import Sample, Stage, WorkBatch
from services.studies import calibration_spec, create_and_start
from services.studies.datasets import load_datasets
from services.studies.kinds import kind_of
from services.studies.kinds.prediction import PredictionRequest, prediction_spec
from services.studies.kinds.update import update_spec
from worker.orchestrator import ContextCache, execute_batch

ROOT = Path(__file__).resolve().parents[2]
LOGS = [ROOT / "examples" / "wf34_s020.csv", ROOT / "examples" / "wf34_s050.csv"]

#: coarse, short runs with the delayed-acceptance surrogate (it is fitted on stored responses)
CASE = CaseDefinition.from_dict(
    {
        "name": "legacy",
        "seed": 5,
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
        "sampler": {
            "n_samples": 24,
            "n_steps": 2,
            "batch_size": 8,
            "delayed_acceptance": True,
            "surrogate_neighbors": 12,
        },
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


def _old(R: np.ndarray) -> np.ndarray:
    """Responses (..., N_RESPONSES groups) as the code before the lateral force stored them:
    the first three of each group."""
    groups = R.shape[-1] // N_RESPONSES
    return R.reshape(*R.shape[:-1], groups, N_RESPONSES)[..., :N_FIRST].reshape(
        *R.shape[:-1], groups * N_FIRST
    )


def _make_old(store: Store, study_id: int) -> None:
    """Rewrite what ``study_id`` stored (sample rows, stage plans, batch results) as the code
    before the lateral force stored it."""
    with store.db.write() as s:
        stage_ids = s.scalars(sa.select(Stage.id).where(Stage.study_id == study_id)).all()
        rows = s.execute(
            sa.select(Sample.stage_id, Sample.sample_index, Sample.responses).where(
                Sample.stage_id.in_(stage_ids)
            )
        ).all()
        for stage_id, index, blob in rows:
            old = _old(np.frombuffer(blob, dtype="<f8").astype(float))
            s.execute(
                sa.update(Sample)
                .where(Sample.stage_id == stage_id, Sample.sample_index == index)
                .values(responses=f64_bytes(old))
            )
        for stage_id, blob in s.execute(
            sa.select(Stage.id, Stage.plan).where(Stage.study_id == study_id)
        ).all():
            if blob is not None:
                s.execute(
                    sa.update(Stage)
                    .where(Stage.id == stage_id)
                    .values(plan=encode(_old_fields(decode(blob, StagePlan))))
                )
        for batch_id, stage_index, blob in s.execute(
            sa.select(WorkBatch.id, WorkBatch.stage_index, WorkBatch.result).where(
                WorkBatch.study_id == study_id, WorkBatch.result.is_not(None)
            )
        ).all():
            if stage_index > 0:
                old = encode(_old_fields(decode(blob, ChainBatchResult)))
                s.execute(sa.update(WorkBatch).where(WorkBatch.id == batch_id).values(result=old))


def _old_fields(obj):
    import dataclasses

    changes = {
        f.name: _old(getattr(obj, f.name))
        for f in dataclasses.fields(obj)
        if f.name.endswith("responses") and isinstance(getattr(obj, f.name), np.ndarray)
    }
    return dataclasses.replace(obj, **changes)


def _run(store: Store, study_id: int, until_stage: int | None = None, batches: int = 0) -> None:
    """Run batches in this process until the study ends (or, with ``until_stage``, until that
    stage is current, then ``batches`` of its batches)."""
    cache = ContextCache()
    while store.studies.get(study_id).status == "running":
        study = store.studies.get(study_id)
        keys = [b.key for b in store.batches.list(study_id, study.current_stage)]
        if until_stage is not None and study.current_stage == until_stage:
            for key in keys[:batches]:
                execute_batch(store, key, cache, None)
            return
        for key in keys:
            execute_batch(store, key, cache, None)


def test_a_calibration_stored_half_way_goes_on_to_the_same_samples(
    store: Store, dataset_ids
) -> None:
    settings = Settings()
    whole = create_and_start(store, calibration_spec(store, settings, CASE, dataset_ids), None)
    _run(store, whole)
    # the same study, stopped in its second tempering stage (one batch of it done) and made old
    study_id = create_and_start(store, calibration_spec(store, settings, CASE, dataset_ids), None)
    _run(store, study_id, until_stage=2, batches=1)
    _make_old(store, study_id)
    old = DatabaseStages(store, study_id).state(1).responses
    assert old.shape == (24, 2 * N_FIRST)
    _run(store, study_id)
    done, ref = store.studies.get(study_id), store.studies.get(whole)
    assert done.status == ref.status == "completed", done.error
    assert done.current_stage == ref.current_stage
    got = store.samples.arrays(study_id, done.current_stage)
    want = store.samples.arrays(whole, ref.current_stage)
    assert got.samples.tobytes() == want.samples.tobytes()
    assert got.log_likelihood.tobytes() == want.log_likelihood.tobytes()
    assert done.log_evidence == ref.log_evidence
    # the stages stored before read with Fy NaN, F, T and z as stored
    stage1 = store.samples.arrays(study_id, 1).responses
    wide = store.samples.arrays(whole, 1).responses
    assert stage1.shape == (24, 2 * N_FIRST)
    R, names = named_responses(stage1, [f"{r}[{d}]" for d in "ab" for r in ("F", "T", "z", "Fy")])
    assert names[3] == "Fy[a]" and R.shape == wide.shape
    assert np.isnan(R[:, 3::N_RESPONSES]).all()
    np.testing.assert_array_equal(_old(R), _old(wide))


def test_an_update_of_a_study_stored_before_is_the_in_memory_update(
    store: Store, dataset_ids
) -> None:
    settings = Settings()
    parent_id = create_and_start(
        store, calibration_spec(store, settings, CASE, dataset_ids[:1]), None
    )
    _run(store, parent_id)
    _make_old(store, parent_id)
    final = DatabaseStages(store, parent_id).state(-1)
    assert final.responses.shape == (24, N_FIRST)
    datasets = load_datasets(store, CASE, dataset_ids)
    likelihood = UpdateLikelihood(StudyModel(CASE, datasets), 1)
    (part,) = likelihood.base_parts(final.responses).values()
    assert part.shape == (24, N_RESPONSES) and np.isnan(part[:, 3]).all()
    np.testing.assert_array_equal(part[:, :N_FIRST], final.responses)

    study_id = create_and_start(
        store, update_spec(store, settings, parent_id, dataset_ids[1:]), None
    )
    _run(store, study_id)
    done = store.studies.get(study_id)
    assert done.status == "completed", done.error
    ref = run_tmcmc(
        likelihood,
        CASE.prior(),
        24,
        CASE.seed + 1,
        CASE.tmcmc_settings(),
        batch_size=8,
        start=PopulationStart(final.samples, (final.beta, final.acceptance_rate)),
    )
    got = store.samples.arrays(study_id, done.current_stage)
    assert got.samples.tobytes() == ref.samples.tobytes()
    assert got.log_likelihood.tobytes() == ref.log_likelihood.tobytes()
    assert done.log_evidence == ref.log_evidence
    # its stage 0: the old dataset's part lacked Fy, so it ran again (as a known part with a
    # non-finite response does), to the F, T and z the parent stored, bit for bit
    stage0 = store.samples.arrays(study_id, 0).responses
    assert stage0.shape == (24, 2 * N_RESPONSES) and np.isfinite(stage0).all()
    assert stage0[:, :N_FIRST].tobytes() == np.ascontiguousarray(final.responses).tobytes()
    assert np.all(stage0[:, 3] == 0.0)  # driven straight


def test_a_prediction_stored_before_reads_back_as_its_result(store: Store, dataset_ids) -> None:
    settings = Settings()
    parent_id = create_and_start(
        store, calibration_spec(store, settings, CASE, dataset_ids[:1]), None
    )
    _run(store, parent_id)
    body = PredictionRequest(study_id=parent_id, dataset_ids=dataset_ids, draws=6, seed=3)
    study_id = create_and_start(store, prediction_spec(store, settings, body), None)
    _run(store, study_id)
    study = store.studies.get(study_id)
    assert study.status == "completed", study.error
    assert study.parent_id == parent_id
    result = study.result["predictions"]
    assert all(set(p["responses"]) == {"F", "T", "z"} for p in result)  # driven straight
    _make_old(store, study_id)
    assert store.samples.arrays(study_id, 0).responses.shape == (6, 2 * N_FIRST)
    preds = kind_of(study.kind).build(store, study).stored(store, study)
    assert [p.to_dict() for p in preds] == result
