"""A TMCMC driver that reports progress: the loop of :func:`scm_core.inference.tmcmc_batched`
written over the same pure stage functions, with hooks for a progress display.

Same inputs, same seeds, same stage functions: the result is bit-identical to
``tmcmc_batched(log_likelihood_batch, prior, n_samples, seed, map, batch_size,
settings=settings)`` for any ``map`` and ``batch_size`` (tested), and ``resume_from`` continues an
interrupted run exactly. ``map`` is consumed lazily, batch by batch, so ``on_batch`` fires as
each batch of chains comes back.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from scm_core.inference.priors import JointPrior
from scm_core.inference.tmcmc import TMCMCResult
from scm_core.inference.tmcmc_stage import (
    LogLikelihoodBatch,
    StageState,
    TMCMCSettings,
    chain_batches,
    evaluate_points,
    initial_samples,
    initial_state,
    plan_stage,
    reduce_stage,
    run_chains,
    stage_status,
)

__all__ = ["StageStart", "run_tmcmc"]

MapFn = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]


@dataclass(frozen=True)
class StageStart:
    """A stage is about to run: its index, tempering exponent and the number of planned
    evaluations (prior points at stage 0, Metropolis proposals after; proposals outside the
    prior support are rejected without a model run, so model runs <= planned)."""

    stage: int
    exponent: float
    planned: int
    n_batches: int


def _check_resume(stages: Sequence[StageState], prior: JointPrior, n: int, seed: int) -> None:
    if not stages:
        raise ValueError("'resume_from' must contain at least stage 0")
    for i, s in enumerate(stages):
        if s.stage != i:
            raise ValueError(f"'resume_from' stage {i} has index {s.stage}")
        if s.seed != int(seed):
            raise ValueError(f"'resume_from' was run with seed {s.seed}, not {seed}")
        if s.n_samples != n or s.dim != prior.dim:
            raise ValueError(
                f"'resume_from' has {s.n_samples} samples of dimension {s.dim}, "
                f"expected {n} of dimension {prior.dim}"
            )


def run_tmcmc(
    log_likelihood_batch: LogLikelihoodBatch,
    prior: JointPrior,
    n_samples: int,
    seed: int,
    settings: TMCMCSettings | None = None,
    map: MapFn = map,
    batch_size: int | None = None,
    resume_from: Sequence[StageState] | None = None,
    on_stage_start: Callable[[StageStart], Any] | None = None,
    on_batch: Callable[[int], Any] | None = None,
    on_stage: Callable[[StageState], Any] | None = None,
) -> TMCMCResult:
    """Run (or resume) TMCMC; see :func:`scm_core.inference.tmcmc_batched`.

    Hooks: ``on_stage_start(StageStart)`` before a stage runs; ``on_batch(k)`` after each batch
    with its number of evaluations; ``on_stage(state)`` after a stage finished (stage 0
    included; not called for the stages of ``resume_from``). Use ``on_stage`` to checkpoint: an
    exception raised there (or a KeyboardInterrupt anywhere) stops the run, and the stages
    saved so far resume it bit-identically.
    """
    settings = settings or TMCMCSettings()
    seed = int(seed)
    if seed < 0:
        raise ValueError(f"'seed' must be a non-negative integer, got {seed!r}")
    if resume_from:
        stages = list(resume_from)
        _check_resume(stages, prior, n_samples, seed)
    else:
        X = initial_samples(prior, n_samples, seed)
        batches = chain_batches(n_samples, batch_size)
        if on_stage_start is not None:
            on_stage_start(StageStart(0, 0.0, n_samples, len(batches)))
        func = partial(evaluate_points, log_likelihood_batch=log_likelihood_batch)
        evals = []
        for r, ev in zip(batches, map(func, [X[r.start : r.stop] for r in batches]), strict=True):
            evals.append(ev)
            if on_batch is not None:
                on_batch(len(r))
        stages = [initial_state(prior, X, evals, seed, settings)]
        if on_stage is not None:
            on_stage(stages[0])

    while (status := stage_status(stages[-1], settings)) is None:
        plan = plan_stage(stages[-1], prior, settings)
        batches = chain_batches(plan.n_chains, batch_size)
        if on_stage_start is not None:
            planned = int(np.sum(plan.chain_length))
            on_stage_start(StageStart(plan.stage, float(plan.exponent), planned, len(batches)))
        func = partial(run_chains, plan, log_likelihood_batch=log_likelihood_batch)
        results = []
        for res in map(func, batches):
            results.append(res)
            if on_batch is not None:
                on_batch(int(np.sum(res.proposed)))
        stages.append(reduce_stage(plan, results))
        if on_stage is not None:
            on_stage(stages[-1])

    final = stages[-1]
    return TMCMCResult(
        samples=final.samples,
        names=prior.names,
        log_evidence=float(final.log_evidence),
        log_evidence_se=math.sqrt(final.log_evidence_var),
        stages=tuple(stages),
        status=status,
    )
