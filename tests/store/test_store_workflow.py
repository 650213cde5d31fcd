"""A whole study driven through the store (a minimal orchestrator) gives the same posterior,
bit for bit, as the in-memory TMCMC loop; stage diagnostics, counters and events follow."""

from __future__ import annotations

import numpy as np
from store_fixtures import in_memory_run, work_one

from services.store import Store


def test_study_through_store_is_bit_identical_to_in_memory(store: Store, toy) -> None:
    expected = in_memory_run(toy)
    study = store.studies.create(toy.spec())
    stage0 = store.studies.start(study.id, toy.batches(toy.n_samples))
    assert stage0 is not None and stage0.status == "planned" and stage0.n_batches == 3
    assert store.studies.start(study.id, toy.batches(toy.n_samples)) is None  # only once

    while work_one(store, toy, "w1"):
        pass

    final = store.studies.get(study.id)
    assert final.status == "completed"
    stages = store.stages.list(study.id)
    assert [s.stage_index for s in stages] == list(range(len(expected)))
    assert all(s.status == "done" for s in stages)
    for rec, exp in zip(stages, expected, strict=True):
        got = toy.state(store, study.id, rec.stage_index)
        assert got.equals(exp), f"stage {rec.stage_index} differs"
        assert rec.exponent == exp.exponent
        arrays = store.samples.arrays(study.id, rec.stage_index)
        assert arrays.samples.tobytes() == exp.samples.tobytes()
        assert arrays.responses.tobytes() == exp.responses.tobytes()
    assert final.log_evidence == expected[-1].log_evidence
    assert final.model_runs == sum(s.model_runs for s in expected)
    assert final.current_stage == len(expected) - 1
    assert stages[-1].exponent == 1.0
    assert np.isinf(expected[0].log_likelihood).any()  # the -inf region was exercised

    kinds = [e.kind for e in store.events.list(study.id, limit=1000)]
    assert kinds[:3] == ["study_created", "study_started", "stage_planned"]
    assert kinds[-2:] == ["stage_done", "study_completed"]
    assert kinds.count("stage_done") == len(expected)
    assert store.stages.ready() == []
