"""Helpers of the store suite: the toy study's stages in memory, and one worker's step of
a minimal orchestrator driving it through the store."""

from __future__ import annotations

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
