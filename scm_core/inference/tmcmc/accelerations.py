"""TMCMC's exact accelerations as small strategy objects (the manner of emcee's moves): what a
stage's planning and its chains call, chosen once from the settings by
:func:`accelerations_of`, instead of branching on :class:`TMCMCSettings`' flags. The flags stay
the settings' (a case's ``[sampler]`` keys, the stored studies); the strategies are built from
them:

* model runs (``early_rejection``): :class:`FullRuns` or :class:`EarlyRejection`, a proposal's
  likelihood parts run one by one (:mod:`scm_core.inference.early_rejection`);
* moves (``delayed_acceptance``, ``surrogate_*``): :class:`PlainMoves` or
  :class:`DelayedAcceptance`, surrogate transitions (:mod:`scm_core.inference.surrogate`);
* inner steps (``surrogate_jumps``): :class:`NoJumps` or :class:`PopulationJumps`
  (:mod:`scm_core.inference.population_jump`).

Each draws, in a chain's fixed order (:func:`~scm_core.inference.tmcmc.chains.draw_numbers`),
exactly the random numbers its branch drew, so results are bit-identical to the flags'.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from scm_core.inference import portable
from scm_core.inference.early_rejection import evaluate_staged, n_parts
from scm_core.inference.population_jump import JUMP_DOF, jump_log_density, jump_proposal
from scm_core.inference.surrogate import ResponseSurrogate, fit_surrogate, supports_surrogate
from scm_core.inference.tmcmc.evaluate import tempered
from scm_core.inference.tmcmc.steps import (
    ChainCounters,
    ChainNumbers,
    ChainState,
    MoveStrategy,
    PlainSteps,
    StepContext,
    SurrogateTransition,
)
from scm_core.inference.tmcmc.types import (
    ChainBatchResult,
    LogLikelihoodBatch,
    StagePlan,
    StageState,
    TMCMCSettings,
)
from scm_core.inference.tmcmc.weights import proposal_factor
from scm_core.inference.walk_space import from_walk, log_proposal_ratio, to_walk

__all__ = [
    "Accelerations",
    "DelayedAcceptance",
    "EarlyRejection",
    "FullRuns",
    "Jumps",
    "ModelRuns",
    "Moves",
    "NoJumps",
    "PlainMoves",
    "PopulationJumps",
    "accelerations_of",
    "surrogate_floor",
]


#: nats below the lowest tempered likelihood part of a stage's starting states at which the
#: surrogate target is floored where the surrogate gives no finite value
FLOOR_MARGIN = 10.0


def surrogate_floor(plan: StagePlan) -> float:
    """The floor of the surrogate's tempered likelihood part (log b~ + exponent log L~) where
    the surrogate gives no finite value: the lowest finite value of the exact part over the
    stage's starting states, less :data:`FLOOR_MARGIN`. A constant of the plan, so pi~ is a
    fixed positive density wherever the prior is (the surrogate chain can reach every state
    the exact chain can)."""
    base = plan.start_log_prior - np.asarray(plan.prior.log_pdf(plan.start_samples), float)
    with np.errstate(invalid="ignore"):
        part = tempered(base, plan.start_log_likelihood, plan.exponent)
    finite = part[np.isfinite(part)]
    return float(finite.min() - FLOOR_MARGIN) if finite.size else 0.0


class ModelRuns(Protocol):
    """How a move's model runs go."""

    def for_likelihood(self, f: LogLikelihoodBatch) -> ModelRuns:
        """The strategy for the likelihood ``f`` (early rejection needs several parts)."""
        ...

    def run(
        self,
        f: LogLikelihoodBatch,
        X: NDArray[np.float64],
        threshold: NDArray[np.float64],
        exponent: float,
        counters: ChainCounters,
    ) -> tuple[Any, NDArray[np.bool_]]:
        """(``f``'s output at X[complete], complete (m,): the proposals whose every part ran)
        at proposals X, which are rejected below ``threshold``; counts the parts run."""
        ...

    def failed(self, counters: ChainCounters, reasons: NDArray[np.str_] | None) -> None:
        """Count the reasons of the complete runs' failures (those of ``f``'s output)."""
        ...


@dataclass(frozen=True)
class FullRuns:
    """Every proposal runs all ``parts`` of the likelihood in one call."""

    parts: int = 1

    def for_likelihood(self, f: LogLikelihoodBatch) -> ModelRuns:
        return FullRuns(n_parts(f))

    def run(
        self,
        f: LogLikelihoodBatch,
        X: NDArray[np.float64],
        threshold: NDArray[np.float64],
        exponent: float,
        counters: ChainCounters,
    ) -> tuple[Any, NDArray[np.bool_]]:
        out = f(X)
        counters.add(part_runs=X.shape[0] * self.parts)
        return out, np.ones(X.shape[0], dtype=bool)

    def failed(self, counters: ChainCounters, reasons: NDArray[np.str_] | None) -> None:
        counters.failed(reasons)


@dataclass(frozen=True)
class EarlyRejection:
    """A proposal's likelihood parts run one by one, stopping once they cannot reach the
    acceptance threshold (exact: the same samples, fewer runs)."""

    def for_likelihood(self, f: LogLikelihoodBatch) -> ModelRuns:
        parts = n_parts(f)
        return self if parts > 1 else FullRuns(parts)

    def run(
        self,
        f: LogLikelihoodBatch,
        X: NDArray[np.float64],
        threshold: NDArray[np.float64],
        exponent: float,
        counters: ChainCounters,
    ) -> tuple[Any, NDArray[np.bool_]]:
        ev = evaluate_staged(f, X, threshold, exponent)  # type: ignore[arg-type]
        counters.add(
            part_runs=ev.part_runs,
            part_runs_saved=ev.part_runs_saved,
            early_rejections=int(np.count_nonzero(ev.rejected)),
            failed_runs=ev.failed_rejected,
        )
        counters.failed(ev.failure)
        return ev.output, ev.complete

    def failed(self, counters: ChainCounters, reasons: NDArray[np.str_] | None) -> None:
        """Nothing: a staged evaluation's reasons are its parts' (counted in :meth:`run`)."""


class Jumps(Protocol):
    """Whether (and how) a surrogate transition's inner steps may be population jumps."""

    def plan_fields(
        self,
        walk: NDArray[np.float64],
        weights: NDArray[np.float64],
        pop_cov: NDArray[np.float64],
        bounds: Any,
    ) -> dict[str, NDArray[np.float64]]:
        """The stage plan's jump fields from the weighted population in walk coordinates."""
        ...

    def for_batch(self, plan: StagePlan, sur: ResponseSurrogate | None) -> Jumps:
        """The strategy of a batch of ``plan``'s chains with the surrogate ``sur``."""
        ...

    def draw(
        self, rng: np.random.Generator, n: int
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]] | None:
        """(jump or not, chi-square variate) of n inner steps of a chain (None: no jumps)."""
        ...

    def propose(
        self,
        ctx: StepContext,
        y: NDArray[np.float64],
        rows: NDArray[np.int64],
        y_prop: NDArray[np.float64],
        q_ratio: NDArray[np.float64],
    ) -> None:
        """Replace the random-walk proposals y_prop (and their log q ratio) at the rows drawn
        as jumps by independence proposals from the population's t."""
        ...

    def count(
        self, counters: ChainCounters, numbers: ChainNumbers, rows: NDArray[np.int64], acc: Any
    ) -> None:
        """Count the jumps among the inner steps ``rows`` and the accepted ones."""
        ...


class NoJumps:
    """Inner steps are random-walk steps."""

    def plan_fields(self, walk: Any, weights: Any, pop_cov: Any, bounds: Any) -> dict:
        return {}

    def for_batch(self, plan: StagePlan, sur: ResponseSurrogate | None) -> Jumps:
        return self

    def draw(self, rng: np.random.Generator, n: int) -> None:
        return None

    def propose(self, ctx: Any, y: Any, rows: Any, y_prop: Any, q_ratio: Any) -> None:
        return None

    def count(self, counters: Any, numbers: Any, rows: Any, acc: Any) -> None:
        return None


@dataclass(frozen=True)
class PopulationJumps:
    """A share ``probability`` of the inner steps are independence proposals from a Student t
    fitted to the stage's weighted population (exact, only on pi~: no model run)."""

    probability: float

    def plan_fields(
        self,
        walk: NDArray[np.float64],
        weights: NDArray[np.float64],
        pop_cov: NDArray[np.float64],
        bounds: Any,
    ) -> dict[str, NDArray[np.float64]]:
        _, jump_chol = proposal_factor(pop_cov, bounds)
        return {
            "jump_mean": portable.weighted_mean(np.ascontiguousarray(walk), weights),
            "jump_chol": jump_chol,
            "jump_inv": portable.lower_inverse(jump_chol),
        }

    def for_batch(self, plan: StagePlan, sur: ResponseSurrogate | None) -> Jumps:
        return self if sur is not None and plan.jump_chol is not None else NO_JUMPS

    def draw(
        self, rng: np.random.Generator, n: int
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        jump_at = rng.random(n) < self.probability
        return jump_at, rng.chisquare(JUMP_DOF, n)

    def propose(
        self,
        ctx: StepContext,
        y: NDArray[np.float64],
        rows: NDArray[np.int64],
        y_prop: NDArray[np.float64],
        q_ratio: NDArray[np.float64],
    ) -> None:
        plan, num, logs = ctx.plan, ctx.numbers, ctx.logs
        jump = num.jump_at[rows]
        if not jump.any():
            return
        u_old = to_walk(y[jump], logs)
        u_new = jump_proposal(
            plan.jump_mean, plan.jump_chol, num.Z[rows[jump]], num.chi2[rows[jump]]
        )
        y_prop[jump] = from_walk(u_new, logs)
        q_ratio[jump] = (
            jump_log_density(u_old, plan.jump_mean, plan.jump_inv)
            - jump_log_density(u_new, plan.jump_mean, plan.jump_inv)
            + log_proposal_ratio(u_new, u_old, logs)
        )

    def count(
        self, counters: ChainCounters, numbers: ChainNumbers, rows: NDArray[np.int64], acc: Any
    ) -> None:
        counters.add(
            population_jumps=int(np.count_nonzero(numbers.jump_at[rows])),
            population_jumps_accepted=int(np.count_nonzero(acc & numbers.jump_at[rows])),
        )


NO_JUMPS = NoJumps()


class Moves(Protocol):
    """What a chain's move is: plain Metropolis steps or a surrogate transition."""

    #: Metropolis steps per move (a surrogate transition's inner steps)
    inner_steps: int

    def surrogate(self, plan: StagePlan, f: LogLikelihoodBatch) -> ResponseSurrogate | None:
        """The stage's surrogate (None: none, or too few training states)."""
        ...

    def draw(self, rng: np.random.Generator, n: int) -> NDArray[np.float64] | None:
        """The log acceptance numbers of a chain's n inner steps (None: no inner steps)."""
        ...

    def keeps_evaluated(self, plan: StagePlan) -> bool:
        """Whether the chains keep the states the model evaluated (a training set)."""
        ...

    def mover(
        self, sur: ResponseSurrogate | None, ctx: StepContext, state: ChainState
    ) -> MoveStrategy:
        """The move of a batch's chains in ``state`` with the stage's surrogate ``sur``."""
        ...

    def training_start(
        self, state: StageState
    ) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        """The surrogate's training set of the stage after ``state`` (before its chains)."""
        ...

    def carried(
        self, plan: StagePlan, results: Sequence[ChainBatchResult]
    ) -> dict[str, NDArray[np.float64] | None]:
        """The training set the stage carries on (``train_samples``, ``train_responses``)."""
        ...


class PlainMoves:
    """A move is one plain Metropolis step, a model run."""

    inner_steps = 1

    def surrogate(self, plan: StagePlan, f: LogLikelihoodBatch) -> None:
        return None

    def draw(self, rng: np.random.Generator, n: int) -> None:
        return None

    def keeps_evaluated(self, plan: StagePlan) -> bool:
        return False

    def mover(
        self, sur: ResponseSurrogate | None, ctx: StepContext, state: ChainState
    ) -> MoveStrategy:
        return PlainSteps(count_inner=False)

    def training_start(self, state: StageState) -> tuple[None, None]:
        return None, None

    def carried(
        self, plan: StagePlan, results: Sequence[ChainBatchResult]
    ) -> dict[str, NDArray[np.float64] | None]:
        return {"train_samples": None, "train_responses": None}


@dataclass(frozen=True)
class DelayedAcceptance:
    """A move is a surrogate transition: ``inner_steps`` Metropolis steps on the surrogate
    target, then one model run corrects (exact whatever the surrogate's error). The surrogate
    (``neighbors``, ``smoothing``) is fitted on the stage's starting states and the newest
    ``memory`` states earlier stages evaluated; where it cannot be, a move is plain steps."""

    inner_steps: int
    neighbors: int
    smoothing: float
    memory: int

    def surrogate(self, plan: StagePlan, f: LogLikelihoodBatch) -> ResponseSurrogate | None:
        if not supports_surrogate(f):
            return None
        samples, responses = plan.start_samples, plan.start_responses
        if plan.train_samples is not None and responses is not None:
            samples = np.concatenate([samples, plan.train_samples])
            responses = np.concatenate([responses, plan.train_responses])
        return fit_surrogate(
            samples,
            responses,
            tuple(f.response_inputs),  # type: ignore[attr-defined]
            self.neighbors,
            self.smoothing,
            getattr(f, "response_outputs", None),
        )

    def draw(self, rng: np.random.Generator, n: int) -> NDArray[np.float64]:
        return portable.log(rng.random(n))

    def keeps_evaluated(self, plan: StagePlan) -> bool:
        return plan.start_responses is not None

    def mover(
        self, sur: ResponseSurrogate | None, ctx: StepContext, state: ChainState
    ) -> MoveStrategy:
        if sur is None:  # its steps count as inner steps
            return PlainSteps(count_inner=True)
        return SurrogateTransition(sur, surrogate_floor(ctx.plan), ctx, state)

    def training_start(
        self, state: StageState
    ) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        if state.responses is None:
            return None, None
        # what earlier stages evaluated, else (stage 0, an update's parent) the population
        if state.train_samples is not None and state.train_responses is not None:
            return state.train_samples, state.train_responses
        return state.samples, state.responses

    def carried(
        self, plan: StagePlan, results: Sequence[ChainBatchResult]
    ) -> dict[str, NDArray[np.float64] | None]:
        """The plan's training set, then the states the stage's model runs evaluated (chain by
        chain, each in step order, whatever the batches), the newest ``memory`` rows."""
        if plan.start_responses is None:
            return {"train_samples": None, "train_responses": None}
        kept = [r for r in results if r.evaluated_counts is not None]
        labels = [np.repeat(r.chain_indices, r.evaluated_counts) for r in kept]
        order = np.argsort(np.concatenate(labels), kind="stable") if labels else np.empty(0, int)
        d, k = plan.start_samples.shape[1], plan.start_responses.shape[1]
        new_x = np.concatenate([r.evaluated_samples for r in kept] or [np.empty((0, d))])[order]
        new_r = np.concatenate([r.evaluated_responses for r in kept] or [np.empty((0, k))])[order]
        old_x = np.empty((0, d)) if plan.train_samples is None else plan.train_samples
        old_r = np.empty((0, k)) if plan.train_responses is None else plan.train_responses
        keep = self.memory
        x = np.concatenate([old_x, new_x])[-keep:] if keep else np.empty((0, d))
        r = np.concatenate([old_r, new_r])[-keep:] if keep else np.empty((0, k))
        return {"train_samples": x, "train_responses": r}


@dataclass(frozen=True)
class Accelerations:
    """The strategies of a run's settings (:func:`accelerations_of`)."""

    moves: Moves
    jumps: Jumps
    runs: ModelRuns


def accelerations_of(settings: TMCMCSettings) -> Accelerations:
    """The accelerations ``settings`` name, chosen once: the one place their flags are read."""
    delayed = settings.delayed_acceptance
    return Accelerations(
        moves=(
            DelayedAcceptance(
                inner_steps=int(settings.surrogate_steps),
                neighbors=settings.surrogate_neighbors,
                smoothing=settings.surrogate_smoothing,
                memory=settings.surrogate_memory,
            )
            if delayed
            else PlainMoves()
        ),
        jumps=(
            PopulationJumps(settings.surrogate_jumps)
            if delayed and settings.surrogate_jumps > 0.0
            else NO_JUMPS
        ),
        runs=EarlyRejection() if settings.early_rejection else FullRuns(),
    )
