"""The data of Transitional MCMC (:mod:`scm_core.inference.tmcmc.stage` has the functions):
sampler settings, a stage's population, a stage's plan, a batch of chains' result and stage 0's
point evaluations. Each is a frozen dataclass whose strict-JSON form (``to_dict``, exact with
``from_dict``) and bit-identical comparison (``equals``) are derived from its fields
(:mod:`scm_core.inference._serial`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from scm_core.inference._serial import dataclass_equal, dataclass_from_dict, dataclass_to_dict
from scm_core.inference.priors import JointPrior
from scm_core.inference.tmcmc.moves import MOVES, move_of
from scm_core.inference.tmcmc.weights import RESAMPLERS
from scm_core.inference.walk_space import PROPOSAL_SCALES

__all__ = [
    "ChainBatchResult",
    "Failures",
    "LogLikelihoodBatch",
    "PointEvaluation",
    "StageCounts",
    "StagePlan",
    "StageState",
    "TMCMCSettings",
    "count_fields",
]

RESAMPLING = tuple(RESAMPLERS)

#: X (m, d) -> log L (m,), or (log L, responses (m, k)), or (log L, responses, log b (m,) or
#: None), or (log L, responses, log b or None, failure (m,)): why each failed run failed, in the
#: model's words (a str per point, "" where the run did not fail; :class:`Failures` counts them)
LogLikelihoodBatch = Callable[
    [NDArray[np.float64]],
    NDArray[np.float64]
    | tuple[NDArray[np.float64], NDArray[np.float64]]
    | tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]
    | tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.str_]],
]

_T = TypeVar("_T", bound="_Fields")


class _Fields:
    """``to_dict``/``from_dict``/``equals`` derived from the dataclass's fields."""

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON dict (non-finite floats as strings); :meth:`from_dict` is exact."""
        return dataclass_to_dict(self)

    @classmethod
    def from_dict(cls: type[_T], data: dict[str, Any]) -> _T:
        return dataclass_from_dict(cls, data)

    def equals(self, other: object) -> bool:
        """Bit-identical comparison of every field (NaN equal to NaN)."""
        return dataclass_equal(self, other)


def _setting(default: Any, doc: str | None = None, **limits: Any) -> Any:
    """A field of :class:`TMCMCSettings` with, for a case's ``[sampler]`` table
    (:mod:`scm_core.calibration.sampler_settings` generates its keys from these fields), its
    description ``doc`` and ``limits``: ``choices`` (the allowed values), ``ge``, ``gt``,
    ``lt`` (bounds; :meth:`TMCMCSettings.__post_init__` checks them too)."""
    return field(default=default, metadata={"doc": doc, **limits})


@dataclass(frozen=True)
class TMCMCSettings(_Fields):
    """Tuning of the sampler; stored with a study so that every stage is reproducible.

    These field defaults are the unaccelerated accurate form (resample-move without a
    surrogate), the sampler's own. A study that names no moves gets the accelerated accurate
    form instead (:data:`scm_core.inference.tmcmc.moves.STUDY_MOVES`, its settings from
    :func:`~scm_core.inference.tmcmc.moves.form_defaults`: waste-free chains of surrogate
    transitions, ``ACCELERATED_STEPS`` inner steps with a share ``ACCELERATED_JUMPS`` of
    population jumps, the log walk and multinomial resampling; docs/sampler.md). Each part
    is exact.

    moves: "resample-move" (default, accurate), "leader" (paper's budget, one run per sample) or
        "waste-free" (Dau & Chopin 2022: under one run per sample, every chain state kept).
    n_steps: Metropolis steps per chain for resample-move; None adapts it per stage with
        :func:`steps_for_acceptance` (``initial_steps`` for stage 1, where no acceptance is known).
        For waste-free: the moves of each chain (states per chain less one; None:
        :data:`~scm_core.inference.tmcmc.moves.WASTE_FREE_STEPS`).
    min_steps, max_steps: clip of the adapted n_steps.
    move_probability: adapted n_steps makes P(chain moves at least once) reach this value.
    target_cov: coefficient of variation of the plausibility weights (Ching & Chen: 1.0).
    beta0: initial proposal scale (Ching & Chen: 0.2).
    target_acceptance, beta_gain, beta_min, beta_max: scale adaptation, see :func:`adapt_beta`.
    stall_tol, stall_stages: "stalled" after ``stall_stages`` consecutive exponent increments
        below ``stall_tol``.
    max_stages: largest stage index (tempering stages after stage 0) before "max_stages".
    early_rejection: run a proposal's likelihood parts (datasets) one by one and stop once they
        cannot reach the acceptance threshold (exact: the same samples, fewer runs; only
        likelihoods with several parts, see :mod:`scm_core.inference.early_rejection`).
    delayed_acceptance: move with a surrogate of the responses before running the model
        (exact: see :mod:`scm_core.inference.surrogate`): each move is ``surrogate_steps``
        Metropolis steps on the surrogate target, then one model run corrects (a surrogate
        transition; 1 step: Christen & Fox's delayed acceptance). Chain lengths then count
        moves: at least ceil(min_steps / surrogate_steps), ceil(initial_steps /
        surrogate_steps) for stage 1, and beta adapts on the inner steps' acceptance.
        surrogate_neighbors and surrogate_smoothing: the surrogate's local RBF interpolant's
        neighbours and smoothing (standardised); surrogate_memory: the newest model-evaluated
        states (with their responses) carried from stage to stage as its training set.
        surrogate_jumps: the probability that an inner step is a population jump instead of a
        random-walk step: an independence proposal from a Student t fitted to the stage's
        weighted population (:mod:`scm_core.inference.population_jump`; exact, only on pi~,
        so it costs no model run; beta adapts on the random-walk steps alone).
    proposal_scale: "linear" (the random walk moves the parameters) or "log" (it moves the log
        of every parameter with a strictly positive prior support: SCM's multiplicative
        trade-offs become straight ridges; exact, see :mod:`scm_core.inference.walk_space`).
    resampling: "systematic" (default; less resampling noise) or "multinomial" (independent
        draws, as Ching & Chen). Either way the reported evidence standard error is the
        genealogy estimate, whose correction for the resampling's own noise follows the
        scheme; see :func:`~scm_core.inference.tmcmc.weights.genealogy_log_evidence_var`.
    """

    moves: str = _setting(
        "resample-move",
        "Move scheme: resample-move (the unaccelerated accurate form), leader (the paper's "
        "form) or waste-free (the accelerated accurate form, a study's default).",
        choices=MOVES,
    )
    n_steps: int | None = _setting(
        None, "Moves per chain: waste-free (default 4), resample-move (default adapted).", ge=1
    )
    min_steps: int = 10
    max_steps: int = 50
    initial_steps: int = 20
    move_probability: float = 0.99
    target_cov: float = _setting(1.0, gt=0.0)
    beta0: float = 0.2
    target_acceptance: float = 0.234
    beta_gain: float = 1.0
    beta_min: float = 0.02
    beta_max: float = 3.0
    stall_tol: float = 1e-8
    stall_stages: int = 3
    max_stages: int = _setting(50, "Stop after this many tempering stages.", ge=1)
    early_rejection: bool = _setting(
        True,
        "Stop simulating a proposal's datasets once they cannot lift it over the acceptance "
        "threshold (exact: the same samples, fewer runs).",
    )
    delayed_acceptance: bool = _setting(
        False,
        "Screen proposals with a surrogate of the responses before simulating them (a study's "
        "default: true for waste-free moves, false for resample-move and leader; exact: the "
        "chain still targets the posterior).",
    )
    surrogate_neighbors: int = 50
    surrogate_smoothing: float = 1e-3
    surrogate_steps: int = _setting(1, ge=1)
    surrogate_memory: int = 20_000
    surrogate_jumps: float = _setting(0.0, ge=0.0, lt=1.0)
    proposal_scale: str = _setting("linear", choices=PROPOSAL_SCALES)
    resampling: str = _setting("systematic", choices=RESAMPLING)

    def __post_init__(self) -> None:
        move_of(self.moves)  # one of MOVES (ValueError names the field)
        if self.n_steps is not None and int(self.n_steps) < 1:
            raise ValueError(f"'n_steps' must be >= 1 or None, got {self.n_steps!r}")
        if not 1 <= self.min_steps <= self.max_steps:
            raise ValueError(
                f"'min_steps' ({self.min_steps}) and 'max_steps' ({self.max_steps}) "
                "must satisfy 1 <= min_steps <= max_steps"
            )
        if self.initial_steps < 1:
            raise ValueError(f"'initial_steps' must be >= 1, got {self.initial_steps!r}")
        if not 0 < self.move_probability < 1:
            raise ValueError(f"'move_probability' must be in (0, 1), got {self.move_probability}")
        if not (math.isfinite(self.target_cov) and self.target_cov > 0):
            raise ValueError(f"'target_cov' must be finite and > 0, got {self.target_cov!r}")
        if not 0 < self.beta_min <= self.beta0 <= self.beta_max:
            raise ValueError(
                f"'beta0' ({self.beta0}) must lie in [beta_min, beta_max] "
                f"= [{self.beta_min}, {self.beta_max}], with beta_min > 0"
            )
        if not 0 < self.target_acceptance < 1:
            raise ValueError(
                f"'target_acceptance' must be in (0, 1), got {self.target_acceptance!r}"
            )
        if self.max_stages < 1:
            raise ValueError(f"'max_stages' must be >= 1, got {self.max_stages!r}")
        if self.stall_stages < 1:
            raise ValueError(f"'stall_stages' must be >= 1, got {self.stall_stages!r}")
        if self.proposal_scale not in PROPOSAL_SCALES:
            raise ValueError(
                f"'proposal_scale' must be 'linear' or 'log', got {self.proposal_scale!r}"
            )
        if self.resampling not in RESAMPLING:
            raise ValueError(f"'resampling' must be one of {RESAMPLING}, got {self.resampling!r}")
        if self.surrogate_memory < 0:
            raise ValueError(f"'surrogate_memory' must be >= 0, got {self.surrogate_memory!r}")
        if not (math.isfinite(self.surrogate_jumps) and 0.0 <= self.surrogate_jumps < 1.0):
            raise ValueError(f"'surrogate_jumps' must be in [0, 1), got {self.surrogate_jumps!r}")
        if self.surrogate_steps < 1:
            raise ValueError(f"'surrogate_steps' must be >= 1, got {self.surrogate_steps!r}")
        if self.surrogate_neighbors < 2:
            raise ValueError(
                f"'surrogate_neighbors' must be >= 2, got {self.surrogate_neighbors!r}"
            )
        if not (math.isfinite(self.surrogate_smoothing) and self.surrogate_smoothing >= 0):
            raise ValueError(
                f"'surrogate_smoothing' must be finite and >= 0, got {self.surrogate_smoothing!r}"
            )


@dataclass(frozen=True)
class Failures:
    """Failed model runs by reason, in the model's words (a study's: the simulator's status,
    e.g. "bottomed_out", or "invalid_configuration"); reasons with a count only, by name.
    Written as a JSON object ``{reason: count}``; ``a + b`` adds the counts."""

    counts: tuple[tuple[str, int], ...] = ()

    @classmethod
    def of(cls, reasons: Iterable[str] | Mapping[str, int]) -> Failures:
        """From a mapping {reason: count} or one reason per failed run ("" is no failure)."""
        tally: dict[str, int] = {}
        items = reasons.items() if isinstance(reasons, Mapping) else ((r, 1) for r in reasons)
        for reason, k in items:
            if reason and int(k):
                tally[str(reason)] = tally.get(str(reason), 0) + int(k)
        return cls(tuple(sorted(tally.items())))

    def __add__(self, other: Failures) -> Failures:
        tally = dict(self.counts)
        for reason, k in other.counts:
            tally[reason] = tally.get(reason, 0) + k
        return Failures.of(tally)

    @property
    def total(self) -> int:
        return sum(k for _, k in self.counts)

    def to_dict(self) -> dict[str, int]:
        return dict(self.counts)

    @classmethod
    def from_dict(cls, data: Mapping[str, int] | None) -> Failures:
        return cls.of(data or {})


def _count(doc: str) -> Any:
    """A counter of :class:`StageCounts`: 0 by default, ``doc`` its description (the API's)."""
    return field(default=0, metadata={"doc": doc})


@dataclass(frozen=True, kw_only=True, eq=False)
class StageCounts(_Fields):
    """What the chains of one stage (or one batch of them) did, counted; a stage's counts are
    its batches' sums (:meth:`plus`). Declared here once: the stages as stored, the API's
    stages, the dashboard's table and the CLI's progress take their lists from these fields
    (:func:`count_fields`), each described by its metadata's ``doc``.
    """

    model_runs: int = _count("Model runs: likelihood evaluations (one per proposal run).")
    failed_runs: int = _count("Model runs that failed (log L = -inf); reasons in failed_by.")
    failed_by: Failures = field(
        default=Failures(),
        metadata={"doc": "Failed model runs by reason (the simulator's status)."},
    )
    out_of_support: int = _count("Proposals outside the prior's support (no run).")
    part_runs: int = _count(
        "Likelihood parts run (a calibration's simulator runs, one per dataset)."
    )
    early_rejections: int = _count("Proposals rejected before all their datasets were simulated.")
    part_runs_saved: int = _count("Simulator runs early rejection saved (exact: the same samples).")
    first_stage_rejections: int = _count(
        "Moves the surrogate turned down (delayed acceptance: no run)."
    )
    surrogate_checks: int = _count("Model runs the surrogate's likelihood was compared with.")
    surrogate_steps: int = _count(
        "Metropolis steps on the surrogate (delayed acceptance's inner steps)."
    )
    surrogate_steps_accepted: int = _count("Of those, the accepted ones.")
    population_jumps: int = _count(
        "Of the surrogate steps, population jumps (independence proposals from the "
        "population's t; the proposal scale adapts on the acceptance of the other steps)."
    )
    population_jumps_accepted: int = _count("Of those, the accepted ones.")

    def count_values(self) -> dict[str, Any]:
        """{counter: value} of these counts (keyword arguments of any class that carries them)."""
        return {f.name: getattr(self, f.name) for f in fields(StageCounts)}

    def counts(self) -> StageCounts:
        """These counts alone (a :class:`StageCounts`, whatever carries them)."""
        return StageCounts(**self.count_values())

    def plus(self, other: StageCounts) -> StageCounts:
        """Counts of two batches (or stages) together."""
        return StageCounts(
            **{f.name: getattr(self, f.name) + getattr(other, f.name) for f in fields(StageCounts)}
        )

    @classmethod
    def from_dict(cls: type[_T], data: dict[str, Any]) -> _T:
        """As :meth:`_Fields.from_dict`, reading the names stored before issue 72 gave each
        counter one name (:meth:`renamed`)."""
        return super().from_dict(StageCounts.renamed(data))  # type: ignore[misc]

    @staticmethod
    def renamed(data: Mapping[str, Any]) -> dict[str, Any]:
        """``data`` with the counters' names stored before issue 72 (``inner_proposed`` for
        ``surrogate_steps``...) read as today's."""
        return {_RENAMED.get(k, k): v for k, v in data.items()}


#: counters' names before issue 72 -> their names now
_RENAMED = {
    "inner_proposed": "surrogate_steps",
    "inner_accepted": "surrogate_steps_accepted",
    "jump_proposed": "population_jumps",
    "jump_accepted": "population_jumps_accepted",
}


def count_fields() -> tuple[tuple[str, str], ...]:
    """(name, description) of every integer counter of :class:`StageCounts`, in order."""
    return tuple((f.name, f.metadata["doc"]) for f in fields(StageCounts) if f.name != "failed_by")


@dataclass(frozen=True, kw_only=True, eq=False)
class StageState(StageCounts):
    """Population after stage ``stage`` (stage 0 = prior draws), targeting prior * L^exponent.

    samples (n, d) in the prior's parameter order; log_likelihood and log_prior (n,);
    responses (n, k) simulated responses returned with the likelihood, or None.
    beta: proposal scale for the *next* stage (already adapted). acceptance_rate: of the moves
    that produced this stage (NaN at stage 0). log_evidence, log_evidence_var: running sum of the
    log-evidence increments and the estimated variance of that sum, the genealogy estimate (see
    :func:`plan_stage`); log_evidence_var_stagewise: the sum of the per-stage delta-method
    terms alone (each stage's mean weight as an iid average; a lower bound), NaN in states
    stored before it was kept (their log_evidence_var is what they reported then).
    The counters of :class:`StageCounts` (model runs, failures by reason, early rejections,
    surrogate steps...) and proposals, accepted: for this stage only.
    n_chains, n_steps: chains run and Metropolis steps per chain (longest chain for "leader").
    ess: effective sample size of the plausibility weights used to resample into this stage
    (n at stage 0). stall_count: consecutive stages with an exponent increment below the stall
    tolerance. seed: study seed. surrogate_error_sum: the sum of |log L~ - log L| (untempered)
    over the surrogate's checks. train_samples, train_responses: with delayed acceptance, the
    newest ``surrogate_memory`` states the model evaluated up to this stage, in chain and step
    order (else None). eve (n,): the stage-0 sample each sample descends from through the
    resampling (its Eve; at stage 0 the first occurrence of the sample, a repeated point being
    one draw), for the log evidence's variance; None in states stored before it was kept.
    """

    stage: int
    exponent: float
    samples: NDArray[np.float64]
    log_likelihood: NDArray[np.float64]
    log_prior: NDArray[np.float64]
    responses: NDArray[np.float64] | None
    beta: float
    acceptance_rate: float
    log_evidence: float
    log_evidence_var: float
    proposals: int
    accepted: int
    n_chains: int
    n_steps: int
    ess: float
    stall_count: int
    seed: int
    surrogate_error_sum: float = 0.0
    train_samples: NDArray[np.float64] | None = None
    train_responses: NDArray[np.float64] | None = None
    eve: NDArray[np.int64] | None = None
    log_evidence_var_stagewise: float = math.nan

    @property
    def n_samples(self) -> int:
        return int(self.samples.shape[0])

    @property
    def dim(self) -> int:
        return int(self.samples.shape[1])

    @property
    def n_unique(self) -> int:
        """Number of distinct sample rows."""
        return int(np.unique(self.samples, axis=0).shape[0])


@dataclass(frozen=True, eq=False)
class StagePlan(_Fields):
    """Everything needed to run the chains of stage ``stage`` and reduce them.

    weights (n,): normalised plausibility weights of the previous samples. parent (n,): indices
    picked by the resampling (``settings.resampling``). chain_start (c,): index into the previous
    samples where each chain starts; chain_length (c,): its number of Metropolis steps. start_*
    are the starting states (copied so that the previous state is not needed by
    :func:`run_chains`).
    proposal_cov (d, d) = beta^2 Cov_w (+ jitter) and its lower Cholesky factor proposal_chol.
    train_samples, train_responses: states the model evaluated in earlier stages and their
    responses, the delayed-acceptance surrogate's training set with the starting states (None
    without delayed acceptance). start_eve (c,): the chain starts' Eves (see
    :class:`StageState`). log_evidence_var: the variance of log Z-hat through this stage (NaN in
    plans stored before it was kept: then the previous variance plus the increment's);
    log_evidence_var_stagewise: the sum of the per-stage terms through this stage (NaN in plans
    stored before it was kept).
    """

    stage: int
    seed: int
    prior: JointPrior
    settings: TMCMCSettings
    exponent: float
    prev_exponent: float
    weights: NDArray[np.float64]
    log_evidence_increment: float
    log_evidence_increment_var: float
    ess: float
    parent: NDArray[np.int64]
    chain_start: NDArray[np.int64]
    chain_length: NDArray[np.int64]
    start_samples: NDArray[np.float64]
    start_log_likelihood: NDArray[np.float64]
    start_log_prior: NDArray[np.float64]
    start_responses: NDArray[np.float64] | None
    proposal_cov: NDArray[np.float64]
    proposal_chol: NDArray[np.float64]
    prev_beta: float
    prev_log_evidence: float
    prev_log_evidence_var: float
    prev_stall_count: int
    n_samples: int
    train_samples: NDArray[np.float64] | None = None
    train_responses: NDArray[np.float64] | None = None
    start_eve: NDArray[np.int64] | None = None
    log_evidence_var: float = math.nan
    log_evidence_var_stagewise: float = math.nan
    jump_mean: NDArray[np.float64] | None = None
    jump_chol: NDArray[np.float64] | None = None
    jump_inv: NDArray[np.float64] | None = None

    @property
    def n_chains(self) -> int:
        return int(self.chain_start.shape[0])


@dataclass(frozen=True, kw_only=True, eq=False)
class ChainBatchResult(StageCounts):
    """Output of :func:`run_chains` for one batch of chains of stage ``stage``.

    For chain chain_indices[i], output_counts[i] consecutive rows of samples / log_likelihood /
    log_prior / responses hold its output (1 final state for resample-move; every visited state,
    one per step, for leader). accepted, proposed (c,): per-chain Metropolis counts (proposals
    outside the prior support count as proposed and rejected). The counters of
    :class:`StageCounts`: the batch's totals. evaluated_counts (c,), evaluated_samples,
    evaluated_responses: with delayed acceptance, the states each chain's model runs evaluated
    with finite responses, chain by chain in step order (the surrogate's next training states;
    else None). surrogate_error (c,): per chain, the sum of |log L~ - log L| over its checked
    evaluations (None without a surrogate).
    """

    stage: int
    chain_indices: NDArray[np.int64]
    output_counts: NDArray[np.int64]
    samples: NDArray[np.float64]
    log_likelihood: NDArray[np.float64]
    log_prior: NDArray[np.float64]
    responses: NDArray[np.float64] | None
    accepted: NDArray[np.int64]
    proposed: NDArray[np.int64]
    surrogate_error: NDArray[np.float64] | None = None
    evaluated_counts: NDArray[np.int64] | None = None
    evaluated_samples: NDArray[np.float64] | None = None
    evaluated_responses: NDArray[np.float64] | None = None


@dataclass(frozen=True, eq=False)
class PointEvaluation(_Fields):
    """Likelihood of a batch of fixed points (stage 0): log L (m,), responses or None, failures,
    log b (m,) where the likelihood gives a base density (else None; see the module doc), the
    likelihood parts run (m x parts), the points run (m less repeated ones; None: m) and, where
    the model gives them, the runs' status codes (m,) (a screening: why runs failed) and the
    failed runs by reason (:class:`Failures`)."""

    log_likelihood: NDArray[np.float64]
    responses: NDArray[np.float64] | None
    failed_runs: int
    log_base: NDArray[np.float64] | None = None
    part_runs: int = 0
    model_runs: int | None = None
    status: NDArray[np.int64] | None = None
    failed_by: Failures = Failures()

    @property
    def runs(self) -> int:
        """Model runs of this evaluation (older stored ones, without the count: one per point)."""
        return self.log_likelihood.shape[0] if self.model_runs is None else int(self.model_runs)
