"""Bit-identical TMCMC results across maps, batch sizes, resumes and serialisation."""

from __future__ import annotations

import json
import math
import multiprocessing
from functools import partial

import numpy as np
import pytest

from scm_core.inference import (
    JointPrior,
    Resume,
    StageHooks,
    StageState,
    TruncatedNormal,
    Uniform,
    rowwise,
    run_tmcmc,
)
from scm_core.inference.tmcmc.stage import (
    ChainBatchResult,
    StagePlan,
    TMCMCSettings,
    evaluate_points,
    initial_samples,
    initial_state,
    plan_stage,
    reduce_stage,
    run_chains,
)

PRIOR = JointPrior(
    {
        "a": Uniform(-3.0, 3.0),
        "b": TruncatedNormal(0.5, 1.0, -2.0, 4.0),
        "c": Uniform(0.0, 2.0),
    }
)
CENTRE = np.array([0.7, 1.2, 0.4])
SCALE = np.array([0.1, 0.2, 0.05])


def loglik(X: np.ndarray, shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian log-likelihood, plus the 'responses' (here the residuals) per point."""
    total = np.zeros(X.shape[0])
    resid = np.empty_like(X)
    for j in range(X.shape[1]):
        r = (X[:, j] - CENTRE[j] - shift) / SCALE[j]
        resid[:, j] = r
        total = total - 0.5 * r * r
    return total, resid


def loglik_scalar(theta: np.ndarray) -> float:
    return float(loglik(theta[None, :])[0][0])


def _same(r1, r2) -> bool:
    return (
        len(r1.stages) == len(r2.stages)
        and all(a.equals(b) for a, b in zip(r1.stages, r2.stages, strict=True))
        and np.array_equal(r1.samples, r2.samples)
        and r1.log_evidence == r2.log_evidence
        and r1.status == r2.status
    )


@pytest.fixture(scope="module")
def reference():
    # n_steps fixed at 3 keeps the batch-size-1 run (one likelihood call per chain step) short
    return run_tmcmc(loglik, PRIOR, n_samples=2000, seed=11, settings=TMCMCSettings(n_steps=3))


@pytest.mark.parametrize("batch_size", [1, 7, 2000])
def test_batch_size_does_not_change_result(reference, batch_size: int) -> None:
    res = run_tmcmc(
        loglik,
        PRIOR,
        n_samples=2000,
        seed=11,
        settings=TMCMCSettings(n_steps=3),
        batch_size=batch_size,
    )
    assert _same(res, reference)
    assert res.responses is not None and res.responses.shape == (2000, 3)


def test_a_split_into_uneven_batches_does_not_change_result(reference) -> None:
    # guided self-scheduling, as `scm-calib calibrate --workers N` cuts a stage
    from services.studies.batching import work_batches

    seen: list[list[int]] = []

    def split(n: int) -> list[range]:
        batches = work_batches(n, batch_size=600, workers=2)
        seen.append([len(b) for b in batches])
        return batches

    res = run_tmcmc(
        loglik, PRIOR, n_samples=2000, seed=11, settings=TMCMCSettings(n_steps=3), split=split
    )
    assert _same(res, reference)
    assert seen[0] == [600, 600, 400, 200, 100, 75, 25]  # shorter batches at a stage's end


def test_process_pool_map_gives_identical_result(reference) -> None:
    with multiprocessing.get_context("fork").Pool(2) as pool:
        res = run_tmcmc(
            partial(loglik, shift=0.0),
            PRIOR,
            n_samples=2000,
            seed=11,
            settings=TMCMCSettings(n_steps=3),
            map=pool.map,
            batch_size=300,
        )
    assert _same(res, reference)


def test_responses_travel_with_samples(reference) -> None:
    # the stored responses are those of the accepted proposals: recompute them from the samples
    expected = loglik(reference.samples)[1]
    assert np.array_equal(reference.responses, expected)
    assert np.array_equal(reference.log_likelihood, loglik(reference.samples)[0])


def test_different_seed_gives_different_result(reference) -> None:
    res = run_tmcmc(loglik, PRIOR, n_samples=2000, seed=12, settings=TMCMCSettings(n_steps=3))
    assert not np.array_equal(res.samples, reference.samples)


def test_scalar_and_batched_interfaces_agree() -> None:
    r1 = run_tmcmc(
        rowwise(loglik_scalar), PRIOR, n_samples=300, seed=5, settings=TMCMCSettings(max_stages=3)
    )
    r2 = run_tmcmc(
        lambda X: loglik(X)[0], PRIOR, n_samples=300, seed=5, settings=TMCMCSettings(max_stages=3)
    )
    assert np.array_equal(r1.samples, r2.samples)
    assert r1.log_evidence == r2.log_evidence


def test_leader_scheme_is_batch_invariant() -> None:
    kw = dict(n_samples=1000, seed=3, settings=TMCMCSettings(moves="leader"))
    r1 = run_tmcmc(loglik, PRIOR, **kw)
    r2 = run_tmcmc(loglik, PRIOR, batch_size=7, **kw)
    assert r1.status == "completed"
    assert _same(r1, r2)


@pytest.mark.parametrize("moves", ["resample-move", "leader", "waste-free"])
def test_resume_from_saved_stages_is_bit_identical(tmp_path, moves: str) -> None:
    saved: list[dict] = []
    kw = dict(n_samples=1000, seed=21, settings=TMCMCSettings(moves=moves))
    full = run_tmcmc(
        loglik, PRIOR, hooks=StageHooks(on_stage=lambda s: saved.append(s.to_dict())), **kw
    )
    assert len(saved) == len(full.stages) >= 4

    # JSON round trip (strict JSON: non-finite floats are encoded as strings)
    text = json.dumps(saved[:3], allow_nan=False)
    stages = [StageState.from_dict(d) for d in json.loads(text)]
    assert all(a.equals(b) for a, b in zip(stages, full.stages[:3], strict=False))
    resumed = run_tmcmc(loglik, PRIOR, start=Resume(stages), **kw)
    assert _same(resumed, full)


def test_result_dict_roundtrip(reference) -> None:
    from scm_core.inference import TMCMCResult

    back = TMCMCResult.from_dict(json.loads(json.dumps(reference.to_dict(), allow_nan=False)))
    assert _same(back, reference)
    assert back.names == ("a", "b", "c")
    assert back.log_evidence_se == reference.log_evidence_se


def test_resume_rejects_other_seed() -> None:
    res = run_tmcmc(loglik, PRIOR, n_samples=200, seed=1, settings=TMCMCSettings(max_stages=1))
    with pytest.raises(ValueError, match="seed"):
        run_tmcmc(loglik, PRIOR, n_samples=200, seed=2, start=Resume(res.stages))


def test_stage_functions_roundtrip_through_json_as_an_orchestrator_would() -> None:
    """Plan -> JSON -> remote batches (shuffled, one duplicated delivery) -> reduce."""
    settings = TMCMCSettings()
    X = initial_samples(PRIOR, 500, seed=4)
    evals = [evaluate_points(X[i : i + 100], loglik) for i in range(0, 500, 100)]
    s0 = initial_state(PRIOR, X, evals, seed=4, settings=settings)
    plan = plan_stage(s0, PRIOR, settings)
    plan2 = StagePlan.from_dict(json.loads(json.dumps(plan.to_dict(), allow_nan=False)))
    batches = [range(i, min(i + 64, plan.n_chains)) for i in range(0, plan.n_chains, 64)]
    local = [run_chains(plan, b, loglik) for b in batches]
    remote = [
        ChainBatchResult.from_dict(json.loads(json.dumps(run_chains(plan2, b, loglik).to_dict())))
        for b in batches[::-1]
    ]
    s1 = reduce_stage(plan, local)
    assert reduce_stage(plan2, remote).equals(s1)
    with pytest.raises(ValueError, match="exactly once"):
        reduce_stage(plan, [*local, local[0]])
    with pytest.raises(ValueError, match="exactly once"):
        reduce_stage(plan, local[1:])
    assert s1.stage == 1 and 0 < s1.exponent <= 1
    assert math.isfinite(s1.log_evidence)
