"""TMCMC driver (Ching & Chen 2007; paper section 2 and 5): loops the pure stage functions.

Parallelism is injected as a ``map`` callable (built-in ``map``, ``multiprocessing.Pool().map``,
a Celery fan-out...) applied to batches of chains; the per-batch function is
``functools.partial(run_chains, plan, log_likelihood_batch=f)``, so ``f`` must be picklable for
process pools (a module-level function or a ``functools.partial`` of one, no lambdas).
Results are bit-identical for a given seed whatever the map and batch size.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.priors import JointPrior
from scm_core.inference.tmcmc.loop import PopulationStart, Tempering, evaluate_zero
from scm_core.inference.tmcmc.stage import (
    LogLikelihoodBatch,
    StageState,
    TMCMCSettings,
    chain_batches,
    run_chains,
)
from scm_core.inference.tmcmc.types import Failures, count_fields

__all__ = [
    "PopulationStart",
    "Resume",
    "StageHooks",
    "StageStart",
    "TMCMCResult",
    "result_of",
    "rowwise",
    "run_tmcmc",
]

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


@dataclass(frozen=True)
class StageHooks:
    """Callbacks of a run: ``on_stage_start(StageStart)`` before a stage runs, ``on_batch(k)``
    after each batch with its number of evaluations, ``on_stage(state)`` after every finished
    stage, stage 0 included (not again for the stages a run resumes from)."""

    on_stage_start: Callable[[StageStart], Any] | None = None
    on_batch: Callable[[int], Any] | None = None
    on_stage: Callable[[StageState], Any] | None = None


@dataclass(frozen=True)
class Resume:
    """Continue a run from its saved stages (stage 0 onwards; same seed, n_samples, settings)."""

    stages: Sequence[StageState]


@dataclass(frozen=True, eq=False)
class TMCMCResult:
    """Outcome of a TMCMC run.

    samples (n, d): final-stage samples (the posterior if status == "completed"), columns in
    ``names`` order. log_evidence, log_evidence_se: log p(D) (natural log) and its delta-method
    standard error, the genealogy estimate (:func:`~scm_core.inference.tmcmc.stage.plan_stage`;
    :attr:`log_evidence_se_stagewise` is the lower bound from the per-stage terms alone).
    stages: every :class:`StageState` from stage 0. status: "completed", "stalled" or
    "max_stages".
    """

    samples: NDArray[np.float64]
    names: tuple[str, ...]
    log_evidence: float
    log_evidence_se: float
    stages: tuple[StageState, ...]
    status: str

    @property
    def final(self) -> StageState:
        return self.stages[-1]

    @property
    def log_evidence_se_stagewise(self) -> float:
        """sqrt of the sum of the per-stage variance terms (each stage's mean weight as an iid
        average): a lower bound of the error; NaN for stages stored before it was kept."""
        return math.sqrt(self.final.log_evidence_var_stagewise)

    @property
    def log_likelihood(self) -> NDArray[np.float64]:
        return self.final.log_likelihood

    @property
    def log_prior(self) -> NDArray[np.float64]:
        return self.final.log_prior

    @property
    def responses(self) -> NDArray[np.float64] | None:
        return self.final.responses

    @property
    def exponents(self) -> NDArray[np.float64]:
        return np.array([s.exponent for s in self.stages])

    @property
    def n_model_runs(self) -> int:
        """Model runs of all stages, stage 0 included."""
        return int(sum(s.model_runs for s in self.stages))

    @property
    def n_failed_runs(self) -> int:
        return int(sum(s.failed_runs for s in self.stages))

    @property
    def failed_by(self) -> Failures:
        """Failed model runs of all stages by reason."""
        return sum((s.failed_by for s in self.stages), Failures())

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON dict of names, status and every stage; :meth:`from_dict` is exact."""
        return {
            "names": list(self.names),
            "status": self.status,
            "stages": [s.to_dict() for s in self.stages],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TMCMCResult:
        stages = tuple(StageState.from_dict(d) for d in data["stages"])
        final = stages[-1]
        return cls(
            samples=final.samples,
            names=tuple(data["names"]),
            log_evidence=float(final.log_evidence),
            log_evidence_se=math.sqrt(final.log_evidence_var),
            stages=stages,
            status=str(data["status"]),
        )

    def diagnostics(self) -> list[dict[str, float | int]]:
        """One row per stage: exponent, beta, acceptance, ESS, unique samples, runs (model runs:
        likelihood evaluations; part runs: their parts, a study's simulator runs, with those early
        rejection saved; moves the surrogate turned down, full evaluations it was checked
        against and its mean |log L~ - log L| there, the acceptance of the surrogate
        transitions' inner steps and of their population jumps), evidence."""
        return [
            {
                "stage": s.stage,
                "exponent": s.exponent,
                "beta": s.beta,
                "acceptance_rate": s.acceptance_rate,
                "ess": s.ess,
                "n_unique": s.n_unique,
                "n_steps": s.n_steps,
                **{name: getattr(s, name) for name, _ in count_fields()},
                "surrogate_error": (
                    s.surrogate_error_sum / s.surrogate_checks if s.surrogate_checks else math.nan
                ),
                "surrogate_acceptance": (
                    s.surrogate_steps_accepted / s.surrogate_steps
                    if s.surrogate_steps
                    else math.nan
                ),
                "population_jump_acceptance": (
                    s.population_jumps_accepted / s.population_jumps
                    if s.population_jumps
                    else math.nan
                ),
                "log_evidence": s.log_evidence,
            }
            for s in self.stages
        ]


class rowwise:  # noqa: N801 - used like a function
    """A batch likelihood from ``log_likelihood(theta)`` of ONE parameter vector (d,) returning
    a float (-inf allowed) or (float, responses (k,)). Picklable when the function is."""

    def __init__(self, log_likelihood: Callable[[NDArray[np.float64]], Any]) -> None:
        self.log_likelihood = log_likelihood

    def __call__(self, X: NDArray[np.float64]):
        outs = [self.log_likelihood(x) for x in X]
        if outs and isinstance(outs[0], tuple):
            ll = np.array([float(o[0]) for o in outs])
            resp = np.array([np.asarray(o[1], dtype=float).reshape(-1) for o in outs])
            return ll, resp
        return np.array([float(o) for o in outs])


def _check_resume(stages: Sequence[StageState], prior: JointPrior, n: int, seed: int) -> None:
    if not stages:
        raise ValueError("a resumed run needs at least stage 0")
    for i, s in enumerate(stages):
        if s.stage != i:
            raise ValueError(f"resumed stage {i} has index {s.stage}")
    last = stages[-1]
    if last.seed != int(seed):
        raise ValueError(f"the resumed stages were run with seed {last.seed}, not {seed}")
    if last.n_samples != n or last.dim != prior.dim:
        raise ValueError(
            f"the resumed stages have {last.n_samples} samples of dimension {last.dim}, "
            f"expected {n} of dimension {prior.dim}"
        )


def run_tmcmc(
    log_likelihood_batch: LogLikelihoodBatch,
    prior: JointPrior,
    n_samples: int = 2000,
    seed: int = 0,
    settings: TMCMCSettings | None = None,
    *,
    map: MapFn = map,
    batch_size: int | None = None,
    split: Callable[[int], Sequence[range]] | None = None,
    start: Resume | PopulationStart | None = None,
    hooks: StageHooks | None = None,
) -> TMCMCResult:
    """Sample the posterior prior(theta) L(theta) / Z with TMCMC and estimate log Z.

    ``log_likelihood_batch(X)`` takes X (m, d) in ``prior.names`` order and returns log L (m,)
    (-inf/NaN allowed: counted as failed runs) or (log L (m,), responses (m, k)) (see
    :class:`rowwise` for a likelihood of one vector). ``settings``: the sampler's tuning
    (:class:`TMCMCSettings`; default resample-move with adaptive steps). Chains of a stage are
    split into batches of ``batch_size`` (None: one batch), or by ``split(n)`` (consecutive
    ranges covering 0..n-1, e.g. guided self-scheduling's shorter batches at a stage's end),
    and run through ``map(func, batches)``; results are bit-identical for any ``map`` and
    split.

    ``start``: None draws stage 0 from the prior; :class:`Resume` continues saved stages
    bit-identically (same seed, n_samples and settings); :class:`PopulationStart` starts from
    an earlier posterior's population (a posterior update: the log evidence is then the
    incremental one). ``hooks``: :class:`StageHooks` called as the run goes; an exception raised
    in one (or a KeyboardInterrupt) stops it.
    """
    settings = settings or TMCMCSettings()
    hooks = hooks or StageHooks()
    seed = int(seed)
    tempering = Tempering(
        prior, settings, n_samples, seed, start if isinstance(start, PopulationStart) else None
    )

    def batches_of(n: int) -> Sequence[range]:
        return split(n) if split else chain_batches(n, batch_size)

    def announce(stage: int, exponent: float, planned: int, n_batches: int) -> None:
        if hooks.on_stage_start is not None:
            hooks.on_stage_start(StageStart(stage, exponent, planned, n_batches))

    def finished(state: StageState) -> None:
        stages.append(state)
        if hooks.on_stage is not None:
            hooks.on_stage(state)

    stages: list[StageState] = []
    if isinstance(start, Resume):
        stages = list(start.stages)
        _check_resume(stages, prior, n_samples, seed)
        step = tempering.next(stages[-1])
    else:
        rows = [tempering.stage_zero_rows(r) for r in batches_of(n_samples)]
        announce(0, 0.0, n_samples, len(rows))
        func = partial(evaluate_zero, log_likelihood_batch=log_likelihood_batch)
        evals = []
        for (X, _, _), ev in zip(rows, map(func, rows), strict=True):
            evals.append(ev)
            if hooks.on_batch is not None:
                hooks.on_batch(len(X))
        step = tempering.begin(evals)
        finished(step.state)

    while step.plan is not None:
        plan = step.plan
        batches = batches_of(plan.n_chains)
        announce(plan.stage, float(plan.exponent), int(np.sum(plan.chain_length)), len(batches))
        func = partial(run_chains, plan, log_likelihood_batch=log_likelihood_batch)
        results = []
        for res in map(func, batches):  # consumed lazily: on_batch fires batch by batch
            results.append(res)
            if hooks.on_batch is not None:
                hooks.on_batch(int(np.sum(res.proposed)))
        step = tempering.advance(plan, results)
        finished(step.state)

    return result_of(stages, prior.names, str(step.status))


def result_of(stages: Sequence[StageState], names: Sequence[str], status: str) -> TMCMCResult:
    """The :class:`TMCMCResult` of a run's stages (from stage 0, wherever they were kept) that
    ended ``status`` ("completed", "stalled", "max_stages")."""
    final = stages[-1]
    return TMCMCResult(
        samples=final.samples,
        names=tuple(names),
        log_evidence=float(final.log_evidence),
        log_evidence_se=math.sqrt(final.log_evidence_var),
        stages=tuple(stages),
        status=str(status),
    )
