"""Kind "prediction": posterior predictions of a finished calibration under other test
conditions (paper section 5.3; DESIGN section 4), as ``scm-calib predict`` makes them.

``POST /predictions {"study_id", "dataset_ids" or "conditions", "draws", "seed"}``: ``draws``
samples of the study's final population (:func:`scm_core.calibration.predict.choose_draws`) are
the work batches' items (with ``"pooled_with"``: other runs of the same calibration, the
draws come from the runs' final populations pooled with equal weight, as ``/pooled`` pools
them); each batch simulates its draws under every target's test conditions
(a stored dataset's, or a condition given as ``TestConditions`` fields with an optional
``name``). The reducer gives per target and response the median and 95 % bands of the steady
means without and with the prediction noise, and the measured value with whether it falls
inside (:func:`scm_core.calibration.predict.summarize_predictions`). Each draw's runs depend on
the draw only, so the result is the CLI's bit for bit however the draws were batched.

Stored: ``case`` the calibrated study's (its priors and settings derived from it), ``n_samples``
the draws, ``seed`` the prediction seed, ``dataset_ids`` the target datasets, ``payload``
``{"study_id", "conditions", "pooled_with"}``; the stage's samples are the draws with their
simulated F, T, z, Fy per target (F, T, z in a prediction stored before Fy: read with Fy NaN);
``result`` ``{"study_id", "pooled_with", "draws", "seed", "level", "predictions": [...]}``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Annotated, Any

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field

from scm_core.calibration import CaseDefinition, DatasetTerms, StudyModel, dataset_terms
from scm_core.calibration.predict import LEVEL, prediction_draws, summarize_predictions
from scm_core.inference._serial import decode_array, encode_array
from scm_core.inference.posterior import pool_samples
from scm_core.seeds import SEED_MAX
from scm_core.signals import LogFormatError
from scm_core.signals.conditions import make_conditions
from scm_core.signals.responses import N_RESPONSES, widened
from services.config import Settings
from services.limits import INT32_MAX, INT64_MAX, LimitError, check_study_size
from services.store import (
    BatchLease,
    BatchOutput,
    ReducedStage,
    ReduceInput,
    Reducer,
    SampleArrays,
    StageAdvance,
    Store,
    StudyRecord,
    StudySpec,
)
from services.store.codec import decode

from ..batching import batch_size_of
from ..comparable import why_not_runs
from ..datasets import check_dataset_ids, load_datasets
from ..errors import StudyRequestError
from ..request_model import RequestModel
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
from .checks import check_runs
from .update import completed_calibration, old_dataset_ids

__all__ = ["KIND", "PredictionRequest", "PredictionResult", "prediction_spec"]

#: draws per work batch: ~1 min of simulator time for one target at the default numerics
DEFAULT_DRAWS_PER_BATCH = 25
MAX_CONDITIONS = 200
#: most runs one prediction pools (a run group's most)
MAX_POOLED = 64


class PredictionRequest(RequestModel):
    """Posterior predictions of a completed calibration (or update) under the test conditions
    of stored datasets or of conditions given here (exactly one of the two)."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "oneOf": [
                {"required": ["dataset_ids"], "properties": {"dataset_ids": {"type": "array"}}},
                {"required": ["conditions"], "properties": {"conditions": {"type": "array"}}},
            ]
        },
    )

    study_id: int = Field(ge=1, le=INT64_MAX, description="The completed calibration.")
    pooled_with: list[Annotated[int, Field(ge=1, le=INT64_MAX)]] = Field(
        default_factory=list,
        max_length=MAX_POOLED - 1,
        description="Other completed runs of the same calibration (the same case but for its "
        "seed, the same data; e.g. the rest of a run group): the draws come from all the runs' "
        "final populations pooled with equal weight, as GET /pooled pools them.",
    )
    dataset_ids: list[Annotated[int, Field(ge=1, le=INT64_MAX)]] | None = Field(
        None,
        min_length=1,
        description="Stored datasets whose test conditions are predicted (and whose measured "
        "means are compared with the bands).",
    )
    conditions: list[dict[str, Any]] | None = Field(
        None,
        min_length=1,
        max_length=MAX_CONDITIONS,
        description="Test conditions to predict: W [N] and the kinematics as a dataset's "
        "metadata gives them (slip with slip_convention, or carriage_speed with rim_speed or "
        "omega), optionally R, b, n_grousers, grouser_height and a name.",
    )
    draws: int = Field(200, ge=1, le=INT32_MAX, description="Posterior samples to simulate.")
    seed: int = Field(0, ge=0, le=SEED_MAX, description="Seed of the draws and the noise.")
    batch_size: int | None = Field(
        None, ge=1, le=INT32_MAX, description="Draws per work batch (does not change results)."
    )
    name: str | None = Field(None, min_length=1, max_length=200)


class PredictionBandOut(BaseModel):
    median: float | None
    lo: float | None
    hi: float | None


class ResponsePredictionOut(BaseModel):
    simulated: PredictionBandOut = Field(description="Band of the simulated steady means.")
    predictive: PredictionBandOut | None = Field(
        description="Band with the prediction-error noise (null without a sigma)."
    )
    measured: float | None
    inside_predictive: bool | None
    inside_simulated: bool | None


class ConditionPredictionOut(BaseModel):
    name: str
    role: str = Field(description="calibration (the study used it) or predicted.")
    conditions: dict[str, Any]
    slip_symmetric: float | None
    n_draws: int
    n_failed: int
    responses: dict[str, ResponsePredictionOut] = Field(
        description="F [N], T [N m], z [m] (and Fy [N] for a steered wheel or a case "
        "fitting it): median and 95 % bands."
    )


class PredictionResult(BaseModel):
    study_id: int
    pooled_with: list[int] = Field(
        default_factory=list, description="The runs pooled with study_id (empty: none)."
    )
    draws: int
    seed: int
    level: float
    predictions: list[ConditionPredictionOut]


def _conditions(items: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each item validated as test conditions, stored as the simulator's keys with a name."""
    out = []
    for i, item in enumerate(items):
        values = dict(item)
        name = values.pop("name", None) or f"condition {i}"
        try:
            cond = make_conditions(values, where=f"conditions.{i}")
        except LogFormatError as exc:
            raise StudyRequestError(str(exc).removeprefix("invalid ")) from None
        out.append({"name": str(name), **cond.to_sim_config()})
    return out


def prediction_spec(store: Store, settings: Settings, body: PredictionRequest) -> StudySpec:
    """A prediction from the completed study ``body.study_id``, checked against the limits and
    at the study's posterior mean on every target; nothing is stored."""
    parent = completed_calibration(
        store, body.study_id, "study_id", "has a posterior to predict from"
    )
    _pooled_runs(store, parent, body.pooled_with)
    if (body.dataset_ids is None) == (body.conditions is None):
        raise StudyRequestError("dataset_ids: give exactly one of dataset_ids and conditions")
    ids = [int(d) for d in body.dataset_ids or ()]
    size = batch_size_of(body.batch_size, None, DEFAULT_DRAWS_PER_BATCH)
    try:
        check_study_size(
            settings,
            n_samples=body.draws,
            max_stages=0,
            steps_per_chain=0,
            dataset_ids=ids,
            batch_size=size,
            samples_field="draws",
        )
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None
    runs = body.draws * max(len(ids), len(body.conditions or ()))
    if runs > settings.max_model_runs_per_study:
        raise StudyRequestError(
            f"draws: {body.draws} draws x {runs // body.draws} targets = {runs} simulator runs "
            f"is over the limit of {settings.max_model_runs_per_study:.3g} (server setting "
            "SCM_CALIB_MAX_MODEL_RUNS_PER_STUDY)"
        )
    if ids:
        check_dataset_ids(store, ids)
    conditions = _conditions(body.conditions) if body.conditions is not None else None
    case = stored_case(parent.case)
    targets = _targets(store, case, ids, conditions)
    theta = np.mean(posterior_of(store, parent, body.pooled_with, int(body.seed)), axis=0)
    model = StudyModel(case, targets)
    problem = model.config_problem(theta)
    where = "dataset_ids" if ids else "conditions"
    if problem is not None:
        k, why = problem
        raise StudyRequestError(f"{where}.{k}: {targets[k].name}: {why}")
    for k in range(len(targets)):
        check_runs(settings, model, theta, k, ids[k] if ids else f"{where}.{k}")
    return StudySpec(
        name=body.name or f"{parent.name} prediction",
        case=parent.case,
        dataset_ids=ids,
        seed=int(body.seed),
        n_samples=int(body.draws),
        batch_size=size,
        kind=KIND.name,
        payload={
            "study_id": parent.id,
            "conditions": conditions,
            "pooled_with": [int(i) for i in body.pooled_with],
        },
        parent_id=parent.id,
    )


def _pooled_runs(store: Store, parent: StudyRecord, ids: Sequence[int]) -> list[StudyRecord]:
    """The completed runs ``ids`` of ``parent``'s calibration; StudyRequestError naming
    ``pooled_with`` when one is missing, listed twice, unfinished or another calibration."""
    if len({parent.id, *ids}) != len(ids) + 1:
        raise StudyRequestError("pooled_with: a study is listed twice (or is study_id itself)")
    runs = [
        completed_calibration(store, int(i), "pooled_with", "has a posterior to pool") for i in ids
    ]
    why = why_not_runs([parent, *runs])
    if why is not None:
        raise StudyRequestError(f"pooled_with: {why}; only runs of one calibration are pooled")
    return runs


def posterior_of(
    store: Store, parent: StudyRecord, pooled_with: Sequence[int], seed: int
) -> NDArray[np.float64]:
    """The posterior samples a prediction draws from: ``parent``'s final population, or with
    ``pooled_with`` the runs' final populations pooled with equal weight
    (:func:`scm_core.inference.posterior.pool_samples`, seeded with the prediction's seed)."""
    finals = [
        store.stages.population(s.id, int(s.current_stage or 0))[1].samples
        for s in [parent, *(store.studies.get(int(i)) for i in pooled_with)]
    ]
    return finals[0] if len(finals) == 1 else pool_samples(finals, seed=seed)


def _targets(
    store: Store,
    case: CaseDefinition,
    dataset_ids: Sequence[int],
    conditions: Sequence[dict[str, Any]] | None,
) -> list[DatasetTerms]:
    if conditions is None:
        return [dataset_terms(d) for d in load_datasets(store, case, dataset_ids)]
    unmeasured = (math.nan,) * N_RESPONSES
    return [
        DatasetTerms(str(c["name"]), {k: v for k, v in c.items() if k != "name"}, unmeasured)
        for c in conditions
    ]


@dataclass
class SimulatedDraws:
    """A batch's result: steady means (draws, targets, N_RESPONSES) [N, N m, m, N] and whether
    each run succeeded (draws, targets)."""

    means: NDArray[np.float64] | None
    ok: NDArray[np.bool_] | None

    def to_dict(self) -> dict[str, Any]:
        return {}

    @classmethod
    def from_dict(cls, _: dict[str, Any]) -> SimulatedDraws:
        return cls(None, None)


@dataclass
class PredictionRun:
    """A prediction's computation (see the module doc); cached per process."""

    case: CaseDefinition
    targets: list[DatasetTerms]
    draws: NDArray[np.float64]
    seed: int
    roles: list[str]
    study_id: int
    pooled_with: list[int]

    @cached_property
    def model_function(self):
        """Draws (m, d) -> (means (m, targets, N_RESPONSES), ok (m, targets))."""
        return StudyModel(self.case, self.targets).simulate_means

    def compute(self, store: Store, lease: BatchLease, model_function: Any) -> BatchOutput:
        means, ok = model_function(self.draws[lease.chain_start : lease.chain_stop])
        return batch_output(lease, SimulatedDraws(np.asarray(means), np.asarray(ok)))

    def summarize(self, means: NDArray[np.float64], ok: NDArray[np.bool_]) -> list[Any]:
        """The predictions (:class:`~scm_core.calibration.predict.ConditionPrediction`, with
        each draw's values) from the draws' steady means (draws, targets, N_RESPONSES) and ok
        mask."""
        return summarize_predictions(
            self.case, self.targets, self.draws, means, ok, self.seed, self.roles
        )

    def stored(self, store: Store, study: StudyRecord) -> list[Any]:
        """The predictions of the completed study ``study`` from its stored stage, the same
        bit for bit as its result's (and with each draw's values, which the result leaves
        out)."""
        meta, population = store.stages.population(study.id, 0)
        n = self.draws.shape[0]
        stored = np.asarray(population.responses, dtype=float).reshape(n, len(self.targets), -1)
        ok = decode_array(meta["ok"]) if "ok" in meta else np.isfinite(stored).all(axis=2)
        return self.summarize(self._widened(stored), np.asarray(ok, dtype=bool))

    def _widened(self, means: NDArray[np.float64]) -> NDArray[np.float64]:
        """Means (draws, targets, k) stored with k responses per target as (draws, targets,
        N_RESPONSES), the later ones NaN (:func:`~scm_core.signals.responses.widened`)."""
        n, t = means.shape[0], len(self.targets)
        return widened(means.reshape(n, -1), t).reshape(n, t, N_RESPONSES)

    def reducer(self, workers: int) -> Reducer:
        """The bands of the study's only stage (``workers`` is not needed)."""

        def reduce(inp: ReduceInput) -> StageAdvance:
            parts = [decode(b, SimulatedDraws) for b in inp.results]
            means = np.concatenate([self._widened(p.means) for p in parts], axis=0)
            ok = np.concatenate([p.ok for p in parts], axis=0)
            preds = self.summarize(means, ok)
            n = self.draws.shape[0]
            nan = np.full(n, np.nan)
            reduced = ReducedStage(
                stage=0,
                population=SampleArrays(self.draws, nan, nan, means.reshape(n, -1)),
                model_runs=n,
                failed_runs=int(np.count_nonzero(~ok.all(axis=1))),
                meta={"seed": self.seed, "ok": encode_array(ok)},
            )
            result = {
                "study_id": self.study_id,
                "pooled_with": self.pooled_with,
                "draws": n,
                "seed": self.seed,
                "level": LEVEL,
                "predictions": [p.to_dict() for p in preds],
            }
            return StageAdvance(reduced, final_status="completed", result=result)

        return reduce


class PredictionKind:
    """The plug-in of kind "prediction" (see :mod:`.base`)."""

    name = "prediction"
    title = "prediction"
    posterior = False
    panel = KindPanel(
        template="kinds/prediction.html", figures=("predictions",), counts="posterior draws"
    )
    http = KindHttp(
        path="/predictions",
        request=PredictionRequest,
        spec=prediction_spec,
        result=PredictionResult,
        description="Simulate ``draws`` samples of a completed calibration's posterior under "
        "the test conditions of stored datasets (``dataset_ids``) or of ``conditions``; the "
        "result gives per target and response (F N, T N m, z m; Fy N for a steered wheel) the "
        "median and 95 % bands "
        "without and with the prediction noise, and the measured mean with whether it falls "
        "inside. Bit-identical to ``scm-calib predict`` for the same seed. Any problem "
        "answers 422 naming the field, and nothing is stored.",
    )
    cli = KindCli("predict", "services.cli.predict:predict_cmd")
    collection = http.path

    def build(self, store: Store, study: StudyRecord) -> PredictionRun:
        payload = dict(study.payload or {})
        parent = store.studies.get(int(payload["study_id"]))
        case = stored_case(study.case)
        ids = list(study.dataset_ids)
        targets = _targets(store, case, ids, payload.get("conditions"))
        posterior = posterior_of(store, parent, payload.get("pooled_with") or (), study.seed)
        used = set(old_dataset_ids(store, parent))
        return PredictionRun(
            case=case,
            targets=targets,
            draws=prediction_draws(case, posterior, study.n_samples, study.seed),
            seed=study.seed,
            roles=["calibration" if d in used else "predicted" for d in ids]
            or ["predicted"] * len(targets),
            study_id=parent.id,
            pooled_with=[int(i) for i in payload.get("pooled_with") or ()],
        )

    def planned_runs(self, plan: bytes | None, batches: Sequence[range]) -> list[int]:
        return one_run_per_item(batches)

    def terms(self, study: StudyRecord) -> StudyTerms:
        """The calibrated study's priors (the columns of the draws) and settings."""
        return case_terms(study.case)


KIND = PredictionKind()
