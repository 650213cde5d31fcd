"""The calibration's TMCMC entry point: :func:`scm_core.inference.tmcmc_batched` with the
progress hooks named as the command line uses them.

Bit-identical to ``tmcmc_batched(log_likelihood_batch, prior, n_samples, seed, map, batch_size,
settings=settings)`` for any ``map`` and ``batch_size`` (tested), and ``resume_from`` continues an
interrupted run exactly.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.priors import JointPrior
from scm_core.inference.tmcmc import StageStart, TMCMCResult, tmcmc_batched
from scm_core.inference.tmcmc_stage import LogLikelihoodBatch, StageState, TMCMCSettings

__all__ = ["StageStart", "run_tmcmc"]

MapFn = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]


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
    stage0_samples: NDArray[np.float64] | None = None,
) -> TMCMCResult:
    """Run (or resume) TMCMC; see :func:`scm_core.inference.tmcmc_batched`.

    Hooks: ``on_stage_start(StageStart)`` before a stage runs; ``on_batch(k)`` after each batch
    with its number of evaluations; ``on_stage(state)`` after a stage finished (stage 0
    included; not called for the stages of ``resume_from``). Use ``on_stage`` to checkpoint: an
    exception raised there (or a KeyboardInterrupt anywhere) stops the run, and the stages
    saved so far resume it bit-identically. ``stage0_samples``: stage 0's points instead of
    prior draws (a posterior update, see :func:`scm_core.inference.tmcmc_batched`).
    """
    return tmcmc_batched(
        log_likelihood_batch,
        prior,
        n_samples=n_samples,
        seed=seed,
        map=map,
        batch_size=batch_size,
        callback=on_stage,
        resume_from=resume_from,
        settings=settings or TMCMCSettings(),
        on_stage_start=on_stage_start,
        on_batch=on_batch,
        stage0_samples=stage0_samples,
    )
