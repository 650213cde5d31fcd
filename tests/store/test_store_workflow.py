"""A whole study driven through the store (a minimal orchestrator) gives the same posterior,
bit for bit, as the in-memory TMCMC loop; stage diagnostics, counters and events follow."""

from __future__ import annotations

import numpy as np

from scm_core.inference.tmcmc_stage import (
    evaluate_points,
    initial_samples,
    initial_state,
    plan_stage,
    reduce_stage,
    run_chains,
    stage_status,
)
from services.store import Store


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
