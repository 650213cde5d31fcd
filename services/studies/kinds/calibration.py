"""Kind "calibration": a Bayesian calibration by Transitional MCMC (paper section 3).

Stage 0 evaluates the likelihood at ``n_samples`` prior draws (rows of
``initial_samples(prior, n_samples, seed)``, one work batch per row range); every later stage
runs the chains of its plan (``scm_core.inference.tmcmc.stage``). The reducer is
``initial_state``/``reduce_stage`` followed by ``plan_stage`` or the end of the study. Plans
and batch results are stored as :mod:`services.store.codec` blobs; a stage's population as
sample rows with the scalar fields of its ``StageState`` as ``meta``. What a study stored
before a response was declared (three responses per dataset: F, T, z) is read with the later
ones NaN (:func:`scm_core.calibration.stored.with_all_responses`), so that it goes on.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, TypeVar

import numpy as np

from scm_core.calibration import CaseDefinition, StudyModel
from scm_core.calibration.stored import with_all_responses
from scm_core.inference.tmcmc.loop import PopulationStart, StageStep, Tempering, evaluate_zero
from scm_core.inference.tmcmc.moves import move_of
from scm_core.inference.tmcmc.stage import (
    ChainBatchResult,
    PointEvaluation,
    StagePlan,
    StageState,
    TMCMCSettings,
    run_chains,
)
from services.config import Settings
from services.limits import LimitError, check_simulator_settings, check_study_size
from services.stages import planned_stage, reduced_stage
from services.store import (
    BatchKey,
    BatchLease,
    BatchOutput,
    PlannedStage,
    ReducedStage,
    ReduceInput,
    Reducer,
    StageAdvance,
    Store,
    StudyRecord,
    StudySpec,
)
from services.store.codec import decode

from ..batching import DEFAULT_BATCH_SIZE, DEFAULT_WORKERS, batch_size_of, work_batches
from ..datasets import check_dataset_ids, load_datasets
from ..errors import StudyRequestError
from ..intake import run_specs
from .base import (
    KindCli,
    KindHttp,
    KindPanel,
    StudyTerms,
    batch_output,
    case_terms,
    one_run_per_item,
    stored_case,
)
from .calibration_request import StudyCreate, build_case
from .checks import check_runs, prior_medians

__all__ = ["KIND", "CalibrationRun", "calibration_spec", "request_specs"]

T = TypeVar("T")


# ---------------------------------------------------------------------------- requests


def check_limits(
    settings: Settings, case: CaseDefinition, dataset_ids: Sequence[int], batch_size: int
) -> None:
    """The study's size (samples, stages, datasets, batches, model runs) and its simulator
    table against the service's limits, before any dataset is read."""
    sampler = case.tmcmc_settings()
    try:
        check_simulator_settings(settings, dict(case.simulator))
        check_study_size(
            settings,
            n_samples=case.sampler.n_samples,
            max_stages=case.sampler.max_stages,
            steps_per_chain=move_of(sampler.moves).max_runs_per_sample(sampler),
            dataset_ids=list(dataset_ids),
            batch_size=batch_size,
        )
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None


def precheck(
    store: Store, settings: Settings, case: CaseDefinition, dataset_ids: Sequence[int]
) -> None:
    """Refuse a case whose simulator configuration cannot be built at the prior medians on
    the datasets' test conditions (the study would fail on its first batch), or whose runs
    are over the service's limits."""
    try:
        model = StudyModel(case, [store.datasets.load(d) for d in dataset_ids])
    except ValueError as exc:
        raise StudyRequestError(f"dataset_ids: {exc}") from None
    theta = prior_medians(case)
    problem = model.config_problem(theta)
    if problem is not None:
        k, why = problem
        raise StudyRequestError(
            f"dataset_ids: dataset {dataset_ids[k]} ({model.datasets[k].name}): {why}"
        )
    for k in range(model.n_datasets):
        check_runs(settings, model, theta, k, dataset_ids[k])


def calibration_spec(
    store: Store,
    settings: Settings,
    case: CaseDefinition,
    dataset_ids: Sequence[int],
    batch_size: int | None = None,
) -> StudySpec:
    """A TMCMC calibration of ``case`` on stored datasets, checked against the limits and at
    the prior medians; nothing is stored. StudyRequestError names the field."""
    size = batch_size_of(batch_size, case.sampler.batch_size, DEFAULT_BATCH_SIZE)
    ids = [int(d) for d in dataset_ids]
    check_limits(settings, case, ids, size)
    check_dataset_ids(store, ids)
    precheck(store, settings, case, ids)
    return StudySpec(
        name=case.name,
        case=case.to_dict(),
        dataset_ids=ids,
        seed=case.seed,
        n_samples=case.sampler.n_samples,
        batch_size=size,
        kind=KIND.name,
    )


def request_specs(store: Store, settings: Settings, body: Any) -> list[StudySpec]:
    """The studies a calibration's request (a :data:`StudyCreate`) asks for: its ``runs``
    repeated runs, or with ``update_of`` one posterior update (kind :mod:`.update`)."""
    if body.update_of is not None:
        from .update import update_request  # the update kind builds on this module

        return [update_request(store, settings, body)]
    case = build_case(body)
    spec = calibration_spec(store, settings, case, body.dataset_ids, body.batch_size)
    return run_specs(case, spec, body.runs)


# ---------------------------------------------------------------------------- computation


@dataclass
class CalibrationRun:
    """What running a calibration's batches needs; rebuilt from the database, cached per
    process."""

    case: CaseDefinition
    model: StudyModel
    settings: TMCMCSettings
    n_samples: int
    seed: int
    _plans: dict[int, StagePlan] = field(default_factory=dict, repr=False)

    @cached_property
    def prior(self):
        return self.case.prior()

    @property
    def start(self) -> PopulationStart | None:
        """Where stage 0 starts (a calibration: the prior's draws)."""
        return None

    @cached_property
    def tempering(self) -> Tempering:
        """The run's stage loop (the same as the CLI's): stage-0 points drawn once per
        process."""
        return Tempering(self.prior, self.settings, self.n_samples, self.seed, self.start)

    @property
    def model_function(self):
        """Points (m, d) -> log-likelihoods (and responses): the simulator's time; the model
        itself, so that early rejection can run its datasets one by one."""
        return self.model

    def compute(self, store: Store, lease: BatchLease, model_function: Any) -> BatchOutput:
        """Run the chains (or stage-0 prior points) of one leased batch; pure computation."""
        if lease.key.stage_index == 0:
            rows = self.tempering.stage_zero_rows(range(lease.chain_start, lease.chain_stop))
            points = evaluate_zero(rows, model_function)
            return batch_output(lease, points, points.runs)
        result = run_chains(self.plan(store, lease.key), lease.chains, model_function)
        return batch_output(lease, result, result.model_runs)

    def result(self, final: StageState) -> dict[str, Any] | None:
        """What the study stores when it completes (a calibration: nothing beyond its
        stages)."""
        return None

    def plan(self, store: Store, key: BatchKey) -> StagePlan:
        """The plan of the batch's stage, read once per process (plans never change once
        stored; the previous stage's is dropped)."""
        plan = self._plans.get(key.stage_index)
        if plan is None:
            blob = store.stages.plan(key.study_id, key.stage_index)
            if blob is None:
                raise ValueError(f"stage {key.stage_index} of study {key.study_id} has no plan")
            plan = self.stored(decode(blob, StagePlan))
            self._plans = {key.stage_index: plan}
        return plan

    def stored(self, obj: T) -> T:
        """A stored plan, batch result or stage of the study with every response the
        likelihood returns (see the module doc)."""
        return with_all_responses(obj, self.model.n_datasets)

    def reducer(self, workers: int) -> Reducer:
        """The stage's population, then the next plan (batches cut for ``workers`` workers,
        see :func:`~services.studies.batching.work_batches`) or the end of the study."""

        def reduce(inp: ReduceInput) -> StageAdvance:
            if inp.stage.stage_index == 0:
                points = [self.stored(decode(b, PointEvaluation)) for b in inp.results]
                step = self.tempering.begin(points)
            else:
                chains = [self.stored(decode(b, ChainBatchResult)) for b in inp.results]
                plan = self.stored(decode(inp.plan or b"", StagePlan))
                step = self.tempering.advance(plan, chains)
            return self.advance_of(step, inp.study.batch_size, workers)

        return reduce

    def advance_of(
        self, step: StageStep, batch_size: int | None, workers: int, result: Any = None
    ) -> StageAdvance:
        """What the store writes for a finished stage: its population, then the next plan
        and its batches, or the end of the study (``result``: what it stores if it completes;
        default :meth:`result`)."""
        state = step.state
        if step.plan is not None:
            batches = work_batches(step.plan.n_chains, batch_size, workers)
            return StageAdvance(reduced_stage(state), planned_stage(step.plan), batches)
        if step.status == "completed":
            done = self.result(state) if result is None else result
            return StageAdvance(reduced_stage(state), final_status="completed", result=done)
        return StageAdvance(
            reduced_stage(state), final_status="stalled", error=f"TMCMC stopped: {step.status}"
        )

    def adopt(
        self,
        store: Store,
        study: StudyRecord,
        states: Sequence[StageState],
        workers: int = DEFAULT_WORKERS,
        result: Any = None,
    ) -> None:
        """Give the new (queued) ``study`` the done stages ``states`` (0..k) of its run kept
        elsewhere (a results folder's checkpoints, an earlier study stopped at its
        ``max_stages``): each stage's plan is made again from the stage before it (planning
        is pure, so it is the plan that stage ran), and what follows stage k by this study's
        settings; the next stages then continue the run bit for bit. ValueError if a stage
        does not follow from the one before under these settings (another run's stages)."""
        states = [self.stored(s) for s in states]
        pairs: list[tuple[PlannedStage | None, ReducedStage]] = [(None, reduced_stage(states[0]))]
        for prev, state in itertools.pairwise(states):
            step = self.tempering.next(prev)
            if step.plan is None or step.plan.exponent != state.exponent:
                raise ValueError(
                    f"stage {state.stage} does not follow from stage {prev.stage} under this "
                    "study's settings"
                )
            pairs.append((planned_stage(step.plan), reduced_stage(state)))
        tail = self.advance_of(self.tempering.next(states[-1]), study.batch_size, workers, result)
        store.stages.adopt(study.id, pairs, tail)


#: the study figures of a kind whose stages temper to a posterior (its page's figures)
POSTERIOR_FIGURES = ("schedule", "prior_posterior", "trace", "pairs", "matrix", "fit")


class CalibrationKind:
    """The plug-in of kind "calibration" (see :mod:`.base`)."""

    name = "calibration"
    title = "calibration"
    http = KindHttp(
        path="/studies",
        request=StudyCreate,
        spec=request_specs,
        result=None,
        summary="Submit a study",
        description="Create a study from a preset of the paper or a full case document on "
        "stored datasets, with optional overrides (``seed``, ``n_samples``, ``moves``, "
        "``n_steps``, ``max_stages``, ``likelihood``, ``name``, ``batch_size``), and start it; "
        "with ``runs`` K, K such studies with the seeds seed, seed + 1, ... as one run group "
        "(the answer is the first). Any problem answers 422 naming the field, and nothing is "
        "stored. With ``update_of``: a posterior update of that completed calibration with the "
        "new ``dataset_ids`` (``seed``, ``name`` and ``batch_size`` may be given; the case is "
        "the earlier study's).",
        reads=False,
        statuses=(401, 413, 422),
    )
    cli = KindCli("calibrate", "services.cli.calibrate:calibrate")
    collection = "/studies"
    posterior = True
    panel = KindPanel(template="kinds/posterior.html", figures=POSTERIOR_FIGURES)

    def build(self, store: Store, study: StudyRecord) -> CalibrationRun:
        case = stored_case(study.case)
        return CalibrationRun(
            case=case,
            model=StudyModel(case, load_datasets(store, case, study.dataset_ids)),
            settings=case.tmcmc_settings(),
            n_samples=study.n_samples,
            seed=study.seed,
        )

    def planned_runs(self, plan: bytes | None, batches: Sequence[range]) -> list[int]:
        """Stage 0: one run per point; later stages: the chains' lengths."""
        if plan is None:
            return one_run_per_item(batches)
        lengths = np.asarray(decode(plan, StagePlan).chain_length, dtype=np.int64)
        return [int(lengths[r.start : r.stop].sum()) for r in batches]

    def terms(self, study: StudyRecord) -> StudyTerms:
        """Priors, TMCMC settings and simulator settings of the study's case."""
        return case_terms(study.case)


KIND = CalibrationKind()
