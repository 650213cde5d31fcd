"""Stages: exactly-once advance under concurrency, rollback on reducer errors, bit-exact sample
storage (with -inf, NaN, -0.0) and sample pagination."""

from __future__ import annotations

import dataclasses
import itertools
import threading
import time

import numpy as np
import pytest
from store_fixtures import in_memory_run, work_one

from scm_core.inference.tmcmc.stage import evaluate_points
from services.stages import reduced_stage
from services.store import BatchKey, InvalidStateError, ReduceInput, StageAdvance, Store


def study_with_stage0_done(store: Store, toy) -> int:
    """A running study whose stage-0 batches all have results (ready to advance)."""
    study = store.studies.create(toy.spec())
    batches = toy.batches(toy.n_samples)
    store.studies.start(study.id, batches)
    X = toy.initial_points(study.seed)
    for i, r in enumerate(batches):
        lease = store.batches.lease("w", study_id=study.id)
        assert lease.key == BatchKey(study.id, 0, i)
        result = evaluate_points(X[r.start : r.stop], toy.log_likelihood)
        assert store.batches.complete(lease.key, toy.output(result, lease.key, r)).status == (
            "stored"
        )
    return study.id


@pytest.mark.parametrize("n_threads", [4])
def test_stage_advances_exactly_once_under_concurrency(
    store: Store, toy, open_store, n_threads: int
) -> None:
    sid = study_with_stage0_done(store, toy)
    calls: list[int] = []
    lock = threading.Lock()

    def slow_reduce(inp: ReduceInput) -> StageAdvance:
        with lock:
            calls.append(inp.stage.stage_index)
        time.sleep(0.2)  # hold the stage while the others try
        return toy.reduce(inp)

    stores = [open_store() for _ in range(n_threads)]
    barrier = threading.Barrier(n_threads)
    outcomes: list[str] = []
    errors: list[BaseException] = []

    def attempt(s: Store) -> None:
        try:
            barrier.wait()
            outcomes.append(s.stages.advance(sid, 0, slow_reduce).status)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=attempt, args=(s,)) for s in stores]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert sorted(outcomes) == ["advanced"] + ["already"] * (n_threads - 1)
    assert calls == [0]
    stages = store.stages.list(sid)
    assert [(s.stage_index, s.status) for s in stages] == [(0, "done"), (1, "planned")]
    assert store.samples.count(sid, 0) == toy.n_samples
    assert len(store.batches.list(sid, 1)) == stages[1].n_batches == 3
    assert [e.kind for e in store.events.list(sid)].count("stage_done") == 1
    assert store.studies.get(sid).current_stage == 1


def test_advance_not_ready_and_reducer_errors_roll_back(store: Store, toy) -> None:
    study = store.studies.create(toy.spec())
    store.studies.start(study.id, toy.batches(toy.n_samples))
    never = pytest.fail  # the reducer must not run while batches are missing
    assert store.stages.advance(study.id, 0, lambda inp: never("called")).status == "not_ready"

    sid = study_with_stage0_done(store, toy)

    def broken(inp: ReduceInput) -> StageAdvance:
        raise RuntimeError("reducer bug")

    with pytest.raises(RuntimeError, match="reducer bug"):
        store.stages.advance(sid, 0, broken)
    assert store.stages.get(sid, 0).status == "running"  # rolled back, not stuck 'reducing'
    assert store.samples.count(sid, 0) == 0
    with pytest.raises(InvalidStateError):
        store.stages.population(sid, 0)  # not done: no population

    def no_next(inp: ReduceInput) -> StageAdvance:
        return StageAdvance(toy.reduce(inp).reduced)  # neither a next plan nor a final status

    with pytest.raises(ValueError, match="final_status"):
        store.stages.advance(sid, 0, no_next)
    assert store.stages.get(sid, 0).status == "running"
    assert store.stages.ready() == [(sid, 0)]

    assert store.stages.advance(sid, 0, toy.reduce).status == "advanced"
    assert store.stages.advance(sid, 0, toy.reduce).status == "already"


def test_repeated_advance_after_the_study_ended_is_already(store: Store, toy) -> None:
    sid = study_with_stage0_done(store, toy)

    def finish(inp: ReduceInput) -> StageAdvance:
        return StageAdvance(toy.reduce(inp).reduced, final_status="completed")

    assert store.stages.advance(sid, 0, finish).status == "advanced"
    again = store.stages.advance(sid, 0, finish)
    assert (again.status, again.study_status) == ("already", "completed")


def test_study_ends_with_final_status(store: Store, toy) -> None:
    sid = study_with_stage0_done(store, toy)

    def stall(inp: ReduceInput) -> StageAdvance:
        state = toy.reduce(inp).reduced
        return StageAdvance(state, final_status="stalled", error="no progress")

    out = store.stages.advance(sid, 0, stall)
    assert (out.status, out.study_status, out.next_stage) == ("advanced", "stalled", None)
    study = store.studies.get(sid)
    assert study.status == "stalled" and study.error == "no progress"
    assert study.model_runs == toy.n_samples and study.log_evidence == 0.0
    assert [e.kind for e in store.events.list(sid)][-1] == "study_stalled"


def special_state(toy, base):
    """The stage-0 state with awkward values: -inf/+inf/NaN log-likelihoods, -inf log-prior,
    -0.0, subnormals and NaN in samples and responses."""
    n = base.n_samples
    X = base.samples.copy()
    X[0] = [-0.0, 5e-324]
    X[1] = [np.nan, np.inf]
    ll = base.log_likelihood.copy()
    ll[:4] = [-np.inf, np.inf, np.nan, -1e308]
    lp = base.log_prior.copy()
    lp[5] = -np.inf
    R = np.arange(n * 3, dtype=float).reshape(n, 3) / 7.0
    R[2] = [np.nan, -0.0, -np.inf]
    return dataclasses.replace(base, samples=X, log_likelihood=ll, log_prior=lp, responses=R)


def test_samples_round_trip_bit_exactly(store: Store, toy) -> None:
    sid = study_with_stage0_done(store, toy)
    kept = {}

    def reduce_special(inp: ReduceInput) -> StageAdvance:
        kept["state"] = state = special_state(toy, toy.reduced_state(inp))
        return StageAdvance(reduced_stage(state), final_status="completed")

    assert store.stages.advance(sid, 0, reduce_special).status == "advanced"
    exp = kept["state"]
    got = store.samples.arrays(sid, 0)
    assert got.samples.dtype == np.float64 and got.samples.shape == exp.samples.shape
    assert got.samples.tobytes() == exp.samples.tobytes()
    assert got.responses.tobytes() == exp.responses.tobytes()
    # double columns: exact values, -inf/+inf kept, NaN read back as NaN
    assert np.array_equal(got.log_likelihood, exp.log_likelihood, equal_nan=True)
    assert np.array_equal(got.log_prior, exp.log_prior, equal_nan=True)
    assert got.log_likelihood[0] == -np.inf and got.log_likelihood[1] == np.inf
    assert np.isnan(got.log_likelihood[2]) and got.log_prior[5] == -np.inf
    state = toy.state(store, sid, 0)
    assert state.equals(exp)
    stage = store.stages.get(sid, 0)
    assert stage.acceptance is None  # NaN at stage 0 is stored as "undefined"


def test_samples_pagination(store: Store, toy) -> None:
    sid = study_with_stage0_done(store, toy)
    store.stages.advance(sid, 0, toy.reduce)
    full = store.samples.arrays(sid, 0)
    start, pages = 0, []
    while start is not None:
        page = store.samples.page(sid, 0, start=start, limit=20)
        assert page.total == toy.n_samples
        pages.append(page)
        start = page.next_start
    assert [len(p.arrays) for p in pages] == [20, 20, 8]
    joined = np.concatenate([p.arrays.samples for p in pages])
    assert joined.tobytes() == full.samples.tobytes()
    joined_r = np.concatenate([p.arrays.responses for p in pages])
    assert np.array_equal(joined_r, full.responses, equal_nan=True)
    for start in (2**63 - 10, 2**63 - 1, 2**64):  # past the index column: empty, no error
        assert len(store.samples.page(sid, 0, start=start, limit=5000).arrays) == 0
    beyond = store.samples.page(sid, 0, start=100, limit=20)
    assert len(beyond.arrays) == 0 and beyond.next_start is None
    assert len(store.samples.arrays(sid, 1)) == 0  # stage 1 planned, no population yet
    plan = toy.plan(store, sid, 1)
    assert plan is not None and plan.stage == 1 and plan.n_chains == toy.n_samples
    assert store.stages.plan(sid, 0) is None


def _adoption(toy, states):
    """(plan, reduced) of each stage of an in-memory run, and what follows the last."""
    from scm_core.inference.tmcmc.stage import plan_stage, stage_status
    from services.stages import planned_stage

    pairs = [(None, reduced_stage(states[0]))]
    for prev, state in itertools.pairwise(states):
        plan = planned_stage(plan_stage(prev, toy.prior, toy.settings))
        pairs.append((plan, reduced_stage(state)))
    last = states[-1]
    if stage_status(last, toy.settings) is None:
        plan = plan_stage(last, toy.prior, toy.settings)
        tail = StageAdvance(pairs[-1][1], planned_stage(plan), toy.batches(plan.n_chains))
    else:
        tail = StageAdvance(pairs[-1][1], final_status="completed", result={"total": 1.5})
    return pairs, tail


def test_a_new_study_adopts_stages_run_elsewhere_and_goes_on_bit_for_bit(store: Store, toy) -> None:
    """Stages 0-2 of the toy run, kept elsewhere, given to a new study in one transaction:
    they read back bit for bit with the study's counters and events as if they had run
    here, stage 3 is planned with pending batches, and working the study to its end gives
    the in-memory run's final population."""
    from services.stages import DatabaseStages, stage_states

    states = in_memory_run(toy)
    assert len(states) > 4
    pairs, tail = _adoption(toy, states[:3])
    sid = store.studies.create(toy.spec()).id
    out = store.stages.adopt(sid, pairs, tail)
    assert (out.status, out.study_status, out.next_stage) == ("advanced", "running", 3)
    study = store.studies.get(sid)
    assert study.current_stage == 3 and study.started_at is not None
    assert study.model_runs == sum(s.model_runs for s in states[:3])
    assert [b.status for b in store.batches.list(sid, 3)] == ["pending"] * len(
        toy.batches(states[2].n_samples)
    )
    rows = store.stages.list(sid)
    assert [r.status for r in rows] == ["done"] * 3 + ["planned"]
    assert rows[1].beta == pairs[1][0].diagnostics["beta"] and rows[2].n_batches == 0
    kinds = [e.kind for e in store.events.list(sid)]
    assert kinds.count("stage_done") == 3 and "study_started" in kinds
    while work_one(store, toy, "w"):
        pass
    got = stage_states(DatabaseStages(store, sid))
    assert len(got) == len(states)
    for a, b in zip(got, states, strict=True):
        assert a.samples.tobytes() == b.samples.tobytes()
        assert a.log_likelihood.tobytes() == b.log_likelihood.tobytes()
    assert store.studies.get(sid).status == "completed"


def test_adopting_a_whole_run_completes_the_study_and_only_a_new_study_adopts(
    store: Store, toy
) -> None:
    states = in_memory_run(toy)
    pairs, tail = _adoption(toy, states)
    sid = store.studies.create(toy.spec()).id
    out = store.stages.adopt(sid, pairs, tail)
    assert (out.status, out.study_status) == ("advanced", "completed")
    study = store.studies.get(sid)
    assert study.result == {"total": 1.5} and study.log_evidence == states[-1].log_evidence
    assert store.batches.list(sid) == []
    with pytest.raises(InvalidStateError, match="cannot adopt"):
        store.stages.adopt(sid, pairs, tail)
    other = store.studies.create(toy.spec(name="other")).id
    with pytest.raises(ValueError, match="stage 0 of the adopted run"):
        store.stages.adopt(other, pairs[1:], tail)
    with pytest.raises(ValueError, match="at least one stage"):
        store.stages.adopt(other, [], tail)
    assert store.studies.get(other).status == "queued"  # nothing written
    assert store.stages.list(other) == []
