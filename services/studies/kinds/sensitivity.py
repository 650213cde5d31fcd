"""Kind "sensitivity": a Morris screening of the soil parameters (paper section 4.4).

The design points are the work batches' "chains"; the Morris analysis is the reducer of the
study's only stage. A screening runs on one dataset (whose test conditions are simulated; its
measurements are not used). Stored: the case, ``payload["design"]`` = the design settings
with every factor's bounds resolved (so the design can be rebuilt exactly, whatever later
defaults become), ``n_samples`` = the number of design points r (d + 1), ``seed`` = the design
seed; the factor box (names, bounds, scale, units: the columns of the stage's samples) is
derived from them when read (:meth:`SensitivityKind.terms`). The stage's
samples are the design points with their steady F, T, z, Fy; the study's ``result`` is
:meth:`scm_core.calibration.SensitivityResult.to_dict`. Outputs depend only on the point, so
the result is bit-identical to ``run_sensitivity`` however the points were batched.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from scm_core.calibration import (
    CaseDefinition,
    MorrisModel,
    MorrisSettings,
    SensitivityDesign,
    StudyModel,
    analyze_sensitivity,
    build_configs,
    sensitivity_design,
)
from scm_core.calibration.failures import failure_counts
from scm_core.inference import LOG_SCALE_KINDS
from scm_core.inference.tmcmc.stage import PointEvaluation
from scm_core.seeds import SEED_MAX
from scm_core.signals import SWTDataset
from scm_core.signals.responses import widened
from scm_core.validation_text import first_error, one_line
from services.config import Settings
from services.limits import (
    INT32_MAX,
    INT64_MAX,
    LimitError,
    check_simulator_settings,
    check_study_size,
)
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
from ..datasets import check_dataset_ids, load_datasets
from ..errors import StudyRequestError
from ..intake import base_case
from ..request_model import PRESET_OR_CASE, RequestModel
from .base import (
    KindCli,
    KindHttp,
    KindPanel,
    StudyTerms,
    batch_output,
    one_run_per_item,
    stored_case,
)
from .checks import check_runs, prior_medians

__all__ = [
    "DEFAULT_POINTS_PER_BATCH",
    "KIND",
    "DesignView",
    "SensitivityRequest",
    "SensitivityRun",
    "design_of",
    "sensitivity_spec",
]

#: design points per work batch: ~1 min of simulator time at the default numerics
DEFAULT_POINTS_PER_BATCH = 14


def _settings(design: SensitivityDesign, joint_k: bool) -> dict[str, Any]:
    return {
        "method": "morris",
        "r": design.design.r,
        "levels": design.design.levels,
        "joint_k": bool(joint_k),
        "bounds": {
            n: [float(design.bounds[i, 0]), float(design.bounds[i, 1])]
            for i, n in enumerate(design.names)
        },
    }


def design_settings(study: StudyRecord) -> dict[str, Any]:
    """The stored design settings of a screening (r, levels, joint_k, resolved bounds)."""
    return dict((study.payload or {})["design"])


def sensitivity_spec(
    store: Store,
    settings: Settings,
    case: CaseDefinition,
    dataset_id: int,
    morris: MorrisSettings,
    *,
    batch_size: int | None = None,
    name: str | None = None,
) -> StudySpec:
    """A Morris screening on one stored dataset, checked against the limits; nothing is
    stored. StudyRequestError names the field (``dataset_id``, ``bounds.<factor>``, ``r``,
    ``levels``)."""
    try:
        check_simulator_settings(settings, dict(case.simulator))
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None
    check_dataset_ids(store, [int(dataset_id)], "dataset_id")
    if morris.r < 2:
        raise StudyRequestError(f"r: need at least 2 trajectories, got {morris.r}")
    if morris.levels < 2 or morris.levels % 2:
        raise StudyRequestError(f"levels: must be an even integer >= 2, got {morris.levels}")
    try:
        design = sensitivity_design(case, morris)
    except ValueError as exc:
        text = str(exc)
        if text.startswith("bounds of "):
            factor, _, rest = text.removeprefix("bounds of ").partition(": ")
            text = f"bounds.{factor}: {rest}"
        elif text.startswith("bounds given for"):
            text = f"bounds: {text.removeprefix('bounds given for ')}"
        raise StudyRequestError(text) from None
    size = batch_size_of(batch_size, None, DEFAULT_POINTS_PER_BATCH)
    try:
        check_study_size(
            settings,
            n_samples=design.n_points,
            max_stages=0,
            steps_per_chain=0,
            dataset_ids=[int(dataset_id)],
            batch_size=size,
            samples_field="r",
        )
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None
    dataset = store.datasets.load(int(dataset_id))
    _check_configuration(case, int(dataset_id), dataset, design)
    model = StudyModel(case, [dataset])
    check_runs(settings, model, prior_medians(case), 0, int(dataset_id))
    return StudySpec(
        name=name or f"{case.name} sensitivity",
        case=case.to_dict(),
        dataset_ids=[int(dataset_id)],
        seed=int(morris.seed),
        n_samples=design.n_points,
        batch_size=size,
        kind=KIND.name,
        payload={"design": _settings(design, morris.joint_k)},
    )


def _check_configuration(
    case: CaseDefinition, dataset_id: int, dataset: SWTDataset, design: SensitivityDesign
) -> None:
    """Refuse a screening whose simulator configuration cannot be built at the centre of the
    factor box on the dataset's test conditions (every run would fail)."""
    model = MorrisModel(design.names, case, dataset)
    lo, hi = design.bounds[:, 0], design.bounds[:, 1]
    log = design.log_scale
    centre = np.where(log, np.sqrt(np.abs(lo * hi)), 0.5 * (lo + hi))
    try:
        build_configs(
            model.nominal, model.simulator, model.dataset.conditions, model.values(centre)
        )
    except (ValidationError, ValueError) as exc:
        field = f"dataset_id: dataset {dataset_id}"
        text = one_line(exc)
        if isinstance(exc, ValidationError):
            loc = first_error(exc)[0]
            factor = (
                "k_star"
                if loc and loc[-1] in ("k_c", "k_phi") and design.names[0] == "k_star"
                else (loc[-1] if loc else "")
            )
            if factor in design.names:
                field = f"bounds.{factor}"
        raise StudyRequestError(
            f"{field}: invalid simulator configuration at the centre of the factor box: {text}"
        ) from None


def design_of(study: StudyRecord, case: CaseDefinition) -> SensitivityDesign:
    """The study's Morris design, rebuilt from its stored settings."""
    return _design(case, design_settings(study), study.seed)


def _design(case: CaseDefinition, cfg: Mapping[str, Any], seed: int) -> SensitivityDesign:
    bounds = {k: (float(v[0]), float(v[1])) for k, v in cfg["bounds"].items()}
    morris = MorrisSettings(
        int(cfg["r"]), int(cfg["levels"]), int(seed), bool(cfg["joint_k"]), bounds
    )
    return sensitivity_design(case, morris)


@dataclass
class SensitivityRun:
    """A sensitivity study's computation (see the module doc); cached per process."""

    design: SensitivityDesign
    model: MorrisModel
    seed: int

    @property
    def model_function(self):
        """Points (m, d) -> (steady means (m, N_RESPONSES) [N, N m, m, N], NaN rows for failed
        runs; the runs' status codes (m,))."""
        return self.model

    def compute(self, store: Store, lease: BatchLease, model_function: Any) -> BatchOutput:
        X = self.design.points[lease.chain_start : lease.chain_stop]
        Y, status = model_function(X)
        Y = np.asarray(Y, dtype=float)
        failed = int(np.count_nonzero(~np.all(np.isfinite(Y), axis=1)))
        nan = np.full(X.shape[0], np.nan)
        return batch_output(lease, PointEvaluation(nan, Y, failed, status=np.asarray(status)))

    def reducer(self, workers: int) -> Reducer:
        """The Morris analysis of the study's only stage (``workers`` is not needed)."""

        def reduce(inp: ReduceInput) -> StageAdvance:
            points = [decode(b, PointEvaluation) for b in inp.results]
            # a batch stored before the later responses were simulated: those are NaN
            Y = np.concatenate([widened(p.responses, 1) for p in points], axis=0)
            # the reasons of failed runs (None if a batch was stored before they were kept)
            known = all(p.status is not None for p in points)
            status = np.concatenate([p.status for p in points]) if known else None
            result = analyze_sensitivity(
                self.design, Y, self.model.dataset.name, status, self.model.keys
            )
            n = self.design.n_points
            nan = np.full(n, np.nan)
            reduced = ReducedStage(
                stage=0,
                population=SampleArrays(self.design.points, nan, nan, Y),
                model_runs=n,
                failed_runs=result.n_failed,
                # the failures by reason, as a calibration's stages keep them (StageCounts)
                meta={"seed": self.seed}
                | ({} if status is None else {"failed_by": failure_counts(status)}),
            )
            return StageAdvance(reduced, final_status="completed", result=result.to_dict())

        return reduce


# ---------------------------------------------------------------------------- HTTP surface


class SensitivityRequest(RequestModel):
    """A Morris screening of the SCM soil parameters (paper section 4.4, Figure 4) under the
    test conditions of one stored dataset, with a preset's or a case document's nominal
    values and simulator settings."""

    model_config = ConfigDict(json_schema_extra=PRESET_OR_CASE)

    preset: str | None = Field(None, description="The paper's case: '1', '2a' or '2b'.")
    case: dict[str, Any] | None = Field(
        None, description="A case document (the TOML case file as JSON); data.files is ignored."
    )
    dataset_id: int = Field(
        ge=1, le=INT64_MAX, description="Stored dataset whose test conditions are simulated."
    )
    r: int = Field(20, ge=2, le=1000, description="Morris trajectories.")
    levels: int = Field(4, ge=2, le=20, description="Grid levels (even).")
    seed: int = Field(0, ge=0, le=SEED_MAX, description="Seed of the design.")
    separate_k: bool = Field(
        False, description="Screen k_c and k_phi apart instead of jointly through k* (eq. 11)."
    )
    bounds: dict[str, tuple[float, float]] | None = Field(
        None, description="Factor bounds {name: [lower, upper]} replacing the defaults."
    )
    name: str | None = Field(None, min_length=1, max_length=200)
    batch_size: int | None = Field(
        None,
        ge=1,
        le=INT32_MAX,
        description="Design points per work batch (at most; shorter at the end).",
    )


def request_spec(store: Store, settings: Settings, body: SensitivityRequest) -> StudySpec:
    """The screening ``POST /sensitivity`` asks for (see :func:`sensitivity_spec`)."""
    return sensitivity_spec(
        store,
        settings,
        base_case(body.preset, body.case),
        body.dataset_id,
        MorrisSettings(body.r, body.levels, body.seed, not body.separate_k, body.bounds),
        batch_size=body.batch_size,
        name=body.name,
    )


class Factor(BaseModel):
    """One screened factor: its box and scale."""

    name: str
    lower: float
    upper: float
    log_scale: bool
    unit: str | None


class DesignView(BaseModel):
    """A screening's design, as its study shows it."""

    dataset_id: int = Field(description="The dataset whose test conditions are simulated.")
    r: int
    levels: int
    joint_k: bool
    factors: list[Factor]
    n_points: int = Field(description="Design points (model runs): r (factors + 1).")


def design_view(study: StudyRecord) -> DesignView:
    """The design of a stored screening (from its terms: the factor box and settings)."""
    terms = KIND.terms(study)
    cfg = terms.sampler
    return DesignView(
        dataset_id=study.dataset_ids[0],
        r=int(cfg["r"]),
        levels=int(cfg["levels"]),
        joint_k=bool(cfg["joint_k"]),
        factors=[
            Factor(
                name=p["name"],
                lower=p["lower"],
                upper=p["upper"],
                log_scale=p["dist"] in LOG_SCALE_KINDS,
                unit=p.get("unit"),
            )
            for p in terms.priors["parameters"]
        ],
        n_points=study.n_samples,
    )


_DESCRIPTION = (
    "Screen the 7 soil parameters of Table 1 (k_c and k_phi jointly through k*, eq. 11, unless "
    "``separate_k``) with r Morris trajectories under the test conditions of ``dataset_id``, "
    "with the case's nominal values and simulator settings. Bounds: ``bounds``, else the "
    "case's prior for a calibrated factor, else the defaults (Table 2 for n, phi, J). Once "
    "completed, the result holds mu, mu*, sigma and the normalised linear (mu* / sum mu*) and "
    "non-linear (sigma / sum sigma) indices of Figure 4 per response F [N], T [N m], z [m] "
    "and factor, with run counts; the design points and their F, T, z are the samples of "
    "stage 0 (``GET /studies/{id}/stages/0/samples.csv``). Any problem answers 422 naming the "
    "field, and nothing is stored."
)


class SensitivityKind:
    """The plug-in of kind "sensitivity" (see :mod:`.base`)."""

    name = "sensitivity"
    title = "sensitivity"
    http = KindHttp(
        path="/sensitivity",
        request=SensitivityRequest,
        spec=request_spec,
        result=None,
        description=_DESCRIPTION,
        fields=DesignView,
        fields_of=design_view,
    )
    cli = KindCli("sensitivity", "services.cli.sensitivity:sensitivity")
    collection = http.path
    posterior = False
    panel = KindPanel(
        template="kinds/sensitivity.html", figures=("indices",), counts="design points (model runs)"
    )

    def build(self, store: Store, study: StudyRecord) -> SensitivityRun:
        case = stored_case(study.case)
        (dataset,) = load_datasets(store, case, study.dataset_ids)
        design = design_of(study, case)
        return SensitivityRun(design, MorrisModel(design.names, case, dataset), study.seed)

    def planned_runs(self, plan: bytes | None, batches: Sequence[range]) -> list[int]:
        return one_run_per_item(batches)

    def terms(self, study: StudyRecord) -> StudyTerms:
        """The factor box (the columns of the design points) and the design settings (cached
        per case, design and seed: a page of studies rebuilds each design once)."""
        return _screening_terms(json.dumps([study.case, design_settings(study), study.seed]))


@lru_cache(maxsize=256)
def _screening_terms(text: str) -> StudyTerms:
    case_doc, cfg, seed = json.loads(text)
    case = CaseDefinition.from_stored(case_doc)
    return StudyTerms(_design(case, cfg, seed).factor_box(), cfg, dict(case.simulator))


KIND = SensitivityKind()
