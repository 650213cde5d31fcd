"""Request and response models of the API (pydantic v2).

Floats that may be undefined (NaN, or infinite where JSON has no number for it) are ``null`` in
responses, except in sample pages, which keep the store's convention: the strings ``"nan"``,
``"inf"`` and ``"-inf"`` (a log-likelihood of ``-inf`` means "outside the support / failed run").
Every error response is ``{"detail": "<one line naming the field>"}``.
"""

from __future__ import annotations

import typing
from datetime import datetime
from typing import Annotated, Any, Generic, Literal, TypeVar

from pydantic import BaseModel, Field, create_model

from scm_core.inference import count_fields
from scm_core.seeds import SEED_MAX
from services.limits import INT32_MAX, INT64_MAX
from services.store import StageRecord, stage_columns
from services.studies.request_model import RequestModel

#: ids: what a BIGINT column holds; counts and sizes: what an INTEGER column holds
ID_MAX = INT64_MAX
COUNT_MAX = INT32_MAX


class _In(RequestModel):
    """Request bodies (:class:`services.studies.request_model.RequestModel`)."""


class ErrorOut(BaseModel):
    detail: str = Field(description="What is wrong, naming the field or resource.")


class PageInfo(BaseModel):
    total: int = Field(description="Items matching the query, in all pages.")
    limit: int
    offset: int
    next_offset: int | None = Field(description="Offset of the next page; null on the last one.")


# ---------------------------------------------------------------------------- health


class HealthOut(BaseModel):
    status: Literal["ok"] = "ok"
    version: str
    mode: Literal["embedded", "distributed"]


class CheckOut(BaseModel):
    ok: bool
    detail: str


class ReadyOut(BaseModel):
    status: Literal["ready", "not ready"]
    detail: str
    checks: dict[str, CheckOut]


class LiveOut(BaseModel):
    status: Literal["live", "not live"]
    detail: str
    checks: dict[str, CheckOut]


# ---------------------------------------------------------------------------- datasets


class DatasetOut(BaseModel):
    id: int
    name: str
    content_hash: str
    source_kind: Literal["timeseries", "summary"]
    filename: str | None
    media_type: str | None
    size_bytes: int
    created_at: datetime
    conditions: dict[str, Any] = Field(description="Test conditions (SI): W, slip, omega, R, ...")
    means: dict[str, float | None] = Field(description="Steady means: F [N], T [Nm], z [m].")
    standard_errors: dict[str, float | None]
    offset: float | None = Field(description="Averaging offset of the stored processing [s].")
    window: list[float | None] | None = Field(description="Averaging window [s].")
    rate_hz: float | None
    n_samples: int | None
    n_trials: int | None
    meta: dict[str, Any] = Field(description="Metadata sent with the upload.")
    created: bool | None = Field(
        None, description="On upload: true if stored now, false if identical content existed."
    )


class DatasetPage(PageInfo):
    items: list[DatasetOut]


class SeriesOut(BaseModel):
    dataset_id: int
    name: str
    units: dict[str, str]
    stride: int = Field(description="Every stride-th sample is returned (max_points).")
    n_total: int = Field(description="Samples in the log.")
    t: list[float]
    raw: dict[str, list[float]]
    filtered: dict[str, list[float]]
    window: list[float] | None
    offset: float | None
    cutoff_hz: float | None
    means: dict[str, float | None]
    standard_errors: dict[str, float | None]


# ---------------------------------------------------------------------------- presets


class PresetOut(BaseModel):
    name: str = Field(description="Preset key: quick, 1, 2a or 2b.")
    case_name: str
    description: str
    seed: int
    parameters: list[str]
    n_samples: int
    moves: str
    expected_model_runs: int = Field(
        description="Model runs one study is expected to make (the sampler's plan of a stage "
        "times the measured number of stages)."
    )
    expected_minutes: float = Field(
        description="Expected wall time of one study on two cores per dataset [min] (measured "
        "seconds per simulation; benchmarks/bench_presets.py)."
    )


# ---------------------------------------------------------------------------- studies


class CancelRequest(_In):
    reason: str | None = Field(None, max_length=500)


class ProgressOut(BaseModel):
    """Where a study is. Evaluations are the Metropolis steps (stage 0: prior points) of the
    current stage; each is one model run unless its proposal falls outside the prior support.
    The ETA covers the current stage, from the study's rate so far (the number of stages still
    to come is not known in advance)."""

    status: str
    stage: int | None
    stage_status: str | None
    exponent: float | None
    evaluations_done: int
    evaluations_planned: int
    batches_done: int
    batches_total: int
    model_runs: int = Field(
        description="Finished stages' model runs plus those the current stage's done batches "
        "ran (never decreases: at a stage's end its runs are exactly these)."
    )
    failed_runs: int = Field(description="Finished stages' failed model runs.")
    failed_by: dict[str, int] = Field(
        default_factory=dict,
        description="Those failed runs by reason (see StageOut.failed_by).",
    )
    elapsed_seconds: float | None
    runs_per_second: float | None
    eta_seconds: float | None = Field(description="Time to finish the current stage.")
    error: str | None


class StudyBrief(BaseModel):
    id: int
    kind: str = Field(
        description="The study's kind: tmcmc a calibration; morris a sensitivity study (see "
        "/sensitivity); others as the service's registry has them."
    )
    name: str
    status: str
    error: str | None
    parameter_names: list[str]
    dataset_ids: list[int]
    seed: int
    n_samples: int
    batch_size: int | None
    current_stage: int | None
    log_evidence: float | None
    model_runs: int
    failed_runs: int
    created_at: datetime
    updated_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    version: int = Field(
        description="Raised by every change of the study's state (also its ETag's source)."
    )
    run_group: int | None = Field(
        None,
        description="Repeated runs submitted together (POST /studies with runs): the id of "
        "the group's first study; null for a study on its own.",
    )


class StudyOut(StudyBrief):
    runs: list[int] = Field(
        default_factory=list,
        description="The studies of its run group, in order (empty on its own); their "
        "agreement: GET /pooled?study_ids=... once they are completed.",
    )
    log_evidence_var: float | None = Field(
        description="Variance of log_evidence: Lee & Whiteley's genealogy estimate, which counts "
        "the error stages carry into each other (docs/calibration.md, 'How sure is log Z'); a "
        "study stored before that estimate keeps the error it reported then."
    )
    case: dict[str, Any]
    priors: dict[str, Any]
    sampler: dict[str, Any]
    payload: dict[str, Any] = Field(
        description='The kind\'s own settings, e.g. {"update_of": 12} for an update.'
    )
    result: dict[str, Any] | None = Field(
        description="The kind's result once finished (an update: log_evidence_increment, "
        "parent_log_evidence, log_evidence_total); null for a calibration."
    )
    progress: ProgressOut


#: the model of a kind's stored result (see services.studies.kinds.base.KindHttp)
ResultT = TypeVar("ResultT")


class KindStudyOut(StudyBrief, Generic[ResultT]):
    """A study of a kind with its own collection (e.g. /predictions): the study, the kind's
    settings (``payload``), progress, and its result once completed."""

    payload: dict[str, Any]
    progress: ProgressOut
    result: ResultT | None


class KindStudyPage(PageInfo, Generic[ResultT]):
    items: list[KindStudyOut[ResultT]]


class StudyPage(PageInfo):
    items: list[StudyBrief]


# ---------------------------------------------------------------------------- case files


#: characters of a TOML case file (the committed ones are 2-5 kB)
CASE_FILE_MAX = 200_000


class CaseFileIn(_In):
    """A case file's text."""

    toml: str = Field(
        min_length=1, max_length=CASE_FILE_MAX, description="The TOML case file's text."
    )


class CaseFileOut(BaseModel):
    case: dict[str, Any] = Field(
        description="The case document, every default filled in (POST /studies' 'case')."
    )


# ---------------------------------------------------------------------------- stages


class _StageBase(BaseModel):
    stage: int
    status: str
    batches: dict[str, int] = Field(description="Work batches by status.")
    created_at: datetime
    finished_at: datetime | None
    failed_by: dict[str, int] = Field(
        default_factory=dict,
        description="A done stage's failed model runs by reason: the simulator's status "
        "(bottomed_out, nonpositive_stiffness, unstable; docs/simulator.md, Statuses) or "
        "invalid_configuration.",
    )
    unique_samples: int | None = Field(
        None, description="Distinct samples in the stage's population (resampling repeats)."
    )


def _stage_out() -> type[BaseModel]:
    """A stage as the API gives it: its own columns, as :class:`services.store.StageRecord`
    declares them (:func:`services.store.stage_columns`), and every counter of the sampler,
    declared once in :class:`scm_core.inference.StageCounts` (null until the stage is done,
    except model and failed runs, which are both)."""
    counters = dict(count_fields())
    hints = typing.get_type_hints(StageRecord)
    columns = {
        f.name: (hints[f.name], Field(description=f.metadata["doc"]))
        for f in stage_columns()
        if f.name not in counters
    }
    counts = {name: (int | None, Field(None, description=doc)) for name, doc in counters.items()}
    return create_model("StageOut", __base__=_StageBase, **columns, **counts)


StageOut = _stage_out()


Num = float | Literal["nan", "inf", "-inf"]


class SamplesPage(PageInfo):
    study_id: int
    stage: int
    stage_status: str
    names: list[str] = Field(description="Columns of samples (the calibrated parameters).")
    response_names: list[str] | None = Field(description="Columns of responses (F/T/z per set).")
    samples: list[list[Num]]
    log_likelihood: list[Num]
    log_prior: list[Num]
    responses: list[list[Num]] | None


class ParameterSummary(BaseModel):
    name: str
    unit: str | None
    mean: float | None
    sd: float | None
    quantiles: dict[str, float | None] = Field(description="Keys q2.5, q25, q50, q75, q97.5.")
    ci95: list[float | None]
    map: float | None = Field(description="Value at the MAP sample (null when pooled).")


class SummaryOut(BaseModel):
    study_id: int
    status: str
    stage: int
    exponent: float | None
    is_posterior: bool = Field(description="True when the stage's exponent is 1.")
    n_samples: int
    names: list[str]
    parameters: list[ParameterSummary]
    correlation: list[list[float | None]]
    map: dict[str, float | None] | None
    map_log_posterior: float | None
    log_evidence: float | None
    log_evidence_sd: float | None
    model_runs: int


class PooledRequest(_In):
    study_ids: list[Annotated[int, Field(ge=1, le=ID_MAX)]] = Field(
        min_length=1, max_length=1000, description="Completed studies with the same parameters."
    )
    n_per_study: int | None = Field(
        None,
        ge=2,
        le=COUNT_MAX,
        description="Samples taken from each study (default: the smallest study's).",
    )
    seed: int = Field(0, ge=0, le=SEED_MAX, description="Seed of the subsampling.")
    include_samples: bool = Field(False, description="Also return the pooled samples.")


class PooledStudy(BaseModel):
    study_id: int
    name: str
    n_samples: int
    log_evidence: float | None
    mean: dict[str, float | None]
    sd: dict[str, float | None]


class ParameterAgreementOut(BaseModel):
    rhat: float | None = Field(description="Rank-normalised split R-hat across the studies.")
    ess_bulk: float | None
    ess_tail: float | None
    study_means: list[float]


class AgreementOut(BaseModel):
    """Do the pooled studies sample the same posterior? Each study's (subsampled) final
    population is one chain of an ArviZ posterior (docs/calibration.md, "Repeated runs")."""

    studies: int
    draws_per_study: int
    rhat_limit: float
    converged: bool = Field(description="Every R-hat at most rhat_limit.")
    disagreeing: list[str]
    few_effective: list[str]
    verdict: str
    parameters: dict[str, ParameterAgreementOut]
    log_evidence_sd: float | None


class ModelClassOut(BaseModel):
    name: str = Field(description="The class: its studies' name and ids.")
    study_ids: list[int] = Field(description="Its runs: completed calibrations, one case.")
    runs: int
    log_evidence: float = Field(description="Mean of the runs' ln Z.")
    se: float = Field(
        description="Standard error of the mean from the runs' spread (one run: its own)."
    )
    spread: float | None = Field(description="Sample sd of the runs' ln Z (null for one run).")
    run_log_evidence: list[float]


class BayesFactorOut(BaseModel):
    better: str
    worse: str
    log_bayes_factor: float = Field(description="ln B = ln Z_better - ln Z_worse.")
    se: float
    dof: float | None = Field(description="Welch-Satterthwaite (null: a normal interval).")
    half_width_95: float
    decided: bool = Field(description="True when the 95 % interval leaves out 0.")
    strength: str = Field(description="Kass & Raftery's (1995) words for ln B.")
    verdict: str


class ComparisonOut(BaseModel):
    """Model classes (runs of one calibration each) ranked by log evidence, and the best one's
    Bayes factor over each other (scm_core.calibration.comparison)."""

    classes: list[ModelClassOut] = Field(description="Best first.")
    bayes_factors: list[BayesFactorOut] = Field(description="The best over each other class.")


class PooledOut(BaseModel):
    study_ids: list[int]
    n_per_study: int
    n_samples: int
    names: list[str]
    parameters: list[ParameterSummary]
    correlation: list[list[float | None]]
    studies: list[PooledStudy]
    agreement: AgreementOut | None = Field(
        description="R-hat, ESS and a convergence verdict across the studies (two or more)."
    )
    samples: list[list[float]] | None = None


class EventOut(BaseModel):
    id: int
    study_id: int | None
    created_at: datetime
    kind: str
    payload: dict[str, Any]
