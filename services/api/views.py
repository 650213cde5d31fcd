"""Read models built from the store: study progress, stage lookup, posterior summaries.

Kept apart from the routers so that the routes stay thin and these can be tested alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from datetime import datetime
from typing import Any, TypeVar

import numpy as np
from fastapi import HTTPException
from numpy.typing import NDArray

from scm_core.calibration import RESPONSE_KEYS
from scm_core.calibration.convergence import RHAT_LIMIT, diagnose_runs
from scm_core.inference import Failures, StageCounts, count_fields
from scm_core.inference.posterior import credible_interval, summarize
from scm_core.jsondoc import finite_or_none
from scm_core.signals.responses import N_RESPONSES, widened
from services.store import NotFoundError, StageRecord, Store, StudyRecord, stage_columns
from services.store.records import Page
from services.studies.kinds import KINDS, kind_of, study_terms
from services.studies.kinds.calibration import KIND as CALIBRATION
from services.studies.kinds.prediction import KIND as PREDICTION

from .schemas import (
    AgreementOut,
    ParameterAgreementOut,
    ParameterSummary,
    ProgressOut,
    StageOut,
    StudyBrief,
    StudyOut,
)

ACTIVE = ("queued", "running")
FINISHED_OK = ("completed", "stalled")


PageT = TypeVar("PageT")


def page_out(model: Callable[..., PageT], page: Page, item: Callable[[Any], Any]) -> PageT:
    """The response model ``model`` of one page of a store listing, ``item`` applied to each
    record (items, total, limit, offset, next_offset)."""
    return model(
        items=[item(r) for r in page.items],
        total=page.total,
        limit=page.limit,
        offset=page.offset,
        next_offset=page.next_offset,
    )


def num_list(a: NDArray[np.float64]) -> list:
    """Floats for JSON, non-finite values as the strings "nan", "inf", "-inf"."""
    a = np.asarray(a, dtype=np.float64)
    if np.isfinite(a).all():
        return a.tolist()

    def one(v: float) -> float | str:
        if math.isfinite(v):
            return v
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")

    if a.ndim == 1:
        return [one(v) for v in a.tolist()]
    return [[one(v) for v in row] for row in a.tolist()]


# ---------------------------------------------------------------------------- studies


def parameter_names(study: StudyRecord) -> list[str]:
    """The columns of the study's samples (derived from its case by its kind)."""
    return study_terms(study).parameter_names


def parameter_units(study: StudyRecord) -> dict[str, str | None]:
    return study_terms(study).parameter_units


def named_responses(R: np.ndarray, names: list[str]) -> tuple[np.ndarray, list[str]]:
    """Stored responses (n, w) with their column names: ``names`` (:func:`response_names`),
    the responses widened to them where they were stored with fewer per dataset (a study
    stored before the lateral force: Fy NaN), else ``r0``, ``r1``, ... when they do not fit
    (an update's, whose responses cover its parent's datasets too)."""
    if R.shape[1] == len(names):
        return R, names
    groups = len(names) // N_RESPONSES
    if groups and R.shape[1] % groups == 0 and R.shape[1] < len(names):
        return widened(R, groups), names
    return R, [f"r{k}" for k in range(R.shape[1])]


def response_names(store: Store, study: StudyRecord) -> list[str]:
    """Columns of the stored responses: F, T, z, Fy per dataset (``F[name]``), as the
    model."""
    out = []
    for did in study.dataset_ids:
        try:
            name = store.datasets.get(did).name
        except NotFoundError:
            name = f"dataset{did}"
        out.extend(f"{r}[{name}]" for r in RESPONSE_KEYS)
    return out


def study_brief(study: StudyRecord) -> StudyBrief:
    return StudyBrief(
        id=study.id,
        kind=study.kind,
        name=study.name,
        status=study.status,
        error=study.error,
        parameter_names=parameter_names(study),
        dataset_ids=list(study.dataset_ids),
        seed=study.seed,
        n_samples=study.n_samples,
        batch_size=study.batch_size,
        current_stage=study.current_stage,
        log_evidence=finite_or_none(study.log_evidence),
        model_runs=study.model_runs,
        failed_runs=study.failed_runs,
        created_at=study.created_at,
        updated_at=study.updated_at,
        started_at=study.started_at,
        finished_at=study.finished_at,
        version=study.version,
        run_group=study.run_group,
    )


def study_out(store: Store, study: StudyRecord) -> StudyOut:
    terms = study_terms(study)
    return StudyOut(
        **study_brief(study).model_dump(),
        runs=[] if study.run_group is None else store.studies.run_group(study.run_group),
        log_evidence_var=finite_or_none(study.log_evidence_var),
        case=study.case,
        priors=terms.priors,
        sampler=terms.sampler,
        payload=dict(study.payload or {}),
        result=study.result,
        progress=study_progress(store, study),
    )


def _stage_evaluations(store: Store, study: StudyRecord, stage: StageRecord) -> tuple:
    """(planned, done, ran, batches_done, batches_total) of a stage, from its batches and (by
    the study's kind) its plan: evaluations planned and done, and the model runs done."""
    batches = store.batches.list(study.id, stage.stage_index)
    plan = store.stages.plan(study.id, stage.stage_index) if stage.stage_index else None
    ranges = [range(b.chain_start, b.chain_stop) for b in batches]
    lengths = kind_of(study.kind).planned_runs(plan, ranges)
    planned = int(sum(lengths))
    done_flags = [b.status == "done" for b in batches]
    done = int(sum(n for n, ok in zip(lengths, done_flags, strict=True) if ok))
    # the runs done batches did (fewer than planned where proposals fell outside the prior or
    # a surrogate stage rejected them): what the stage's reduction adds to the study's runs
    ran = int(
        sum(
            (n if b.model_runs is None else b.model_runs)
            for n, b in zip(lengths, batches, strict=True)
            if b.status == "done"
        )
    )
    return planned, done, ran, int(sum(done_flags)), len(batches)


#: most predictions of one study the dashboard lists
PREDICTIONS_SHOWN = 500


def predictions_of(store: Store, study: StudyRecord) -> list[StudyRecord]:
    """The prediction studies made from ``study``'s posterior, newest first (one indexed
    query: a study's parent is a column of the store)."""
    page = store.studies.list(kind=PREDICTION.name, parent=study.id, limit=PREDICTIONS_SHOWN)
    return list(page.items)


def kind_posts() -> dict[str, str]:
    """Where a study of each kind is submitted (``POST``), by kind name, as the kinds declare
    it (``StudyKind.http``; a kind made by another kind's route, an update, at its collection):
    the dashboard's forms post there."""
    return {
        name: kind.http.path if kind.http is not None else kind.collection
        for name, kind in KINDS.items()
    }


def next_step_posts() -> dict[str, str]:
    """Where the dashboard's forms that start from a completed study post, from the kinds'
    declarations: ``update_post`` (the calibration kind's create route takes ``update_of``)
    and ``predict_post``."""
    posts = kind_posts()
    return {"update_post": posts[CALIBRATION.name], "predict_post": posts[PREDICTION.name]}


def failed_by(store: Store, study: StudyRecord) -> dict[str, int]:
    """The study's failed runs by reason: its done stages' (none looked up when none failed)."""
    if not study.failed_runs:
        return {}
    total = Failures()
    for stage in store.stages.list(study.id):
        total = total + Failures.from_dict(stage.meta.get("failed_by"))
    return total.to_dict()


def study_progress(store: Store, study: StudyRecord, now: datetime | None = None) -> ProgressOut:
    """The progress block of ``GET /studies/{id}`` (see :class:`ProgressOut`)."""
    now = now or store.db.now()
    stage = None
    if study.current_stage is not None:
        try:
            stage = store.stages.get(study.id, study.current_stage)
        except NotFoundError:
            stage = None
    planned = done = ran = batches_done = batches_total = 0
    runs = study.model_runs
    if stage is not None:
        planned, done, ran, batches_done, batches_total = _stage_evaluations(store, study, stage)
        if stage.status == "done":
            done = planned
        else:
            runs += ran
    elapsed = rate = eta = None
    if study.started_at is not None:
        end = study.finished_at or now
        elapsed = max((end - study.started_at).total_seconds(), 0.0)
        if elapsed > 0 and runs > 0:
            rate = runs / elapsed
    if study.status in ACTIVE:
        if stage is not None and rate:
            eta = max(planned - done, 0) / rate
    elif study.status in FINISHED_OK:
        eta = 0.0
    return ProgressOut(
        status=study.status,
        stage=study.current_stage,
        stage_status=None if stage is None else stage.status,
        exponent=None if stage is None else finite_or_none(stage.exponent),
        evaluations_done=done,
        evaluations_planned=planned,
        batches_done=batches_done,
        batches_total=batches_total,
        model_runs=int(runs),
        failed_runs=study.failed_runs,
        failed_by=failed_by(store, study),
        elapsed_seconds=elapsed,
        runs_per_second=rate,
        eta_seconds=eta,
        error=study.error,
    )


def stage_counts(stage: StageRecord) -> dict[str, Any]:
    """A stage's counters (:class:`~scm_core.inference.StageCounts`, by the names the version
    that stored it used): null until it is done, except its model and failed runs; its failed
    runs by reason."""
    stored = StageCounts.renamed(stage.meta)
    counts = StageCounts.from_dict(stored)
    out: dict[str, Any] = {
        name: getattr(counts, name) if name in stored else None for name, _ in count_fields()
    }
    out.update(
        model_runs=stage.model_runs,
        failed_runs=stage.failed_runs,
        failed_by=counts.failed_by.to_dict(),
    )
    return out


def stage_out(store: Store, stage: StageRecord) -> StageOut:
    """A stage for the API: its own columns (non-finite floats as null), its batches by
    status, its counters."""
    columns = {
        f.name: finite_or_none(getattr(stage, f.name))
        if f.metadata["column"] == "real"
        else getattr(stage, f.name)
        for f in stage_columns()
    }
    return StageOut(
        stage=stage.stage_index,
        status=stage.status,
        batches=store.batches.counts(stage.study_id, stage.stage_index),
        **(columns | stage_counts(stage)),
        unique_samples=stage.meta.get("unique_samples"),
        created_at=stage.created_at,
        finished_at=stage.finished_at,
    )


def resolve_stage(store: Store, study_id: int, j: int) -> StageRecord:
    """Stage ``j`` of a study; negative ``j`` counts finished stages from the end (-1: the
    last finished stage)."""
    store.studies.get(study_id)  # 404 for an unknown study
    stages = store.stages.list(study_id)
    if j < 0:
        done = [s for s in stages if s.status == "done"]
        if not done:
            raise HTTPException(409, f"study {study_id} has no finished stage yet")
        if -j > len(done):
            raise HTTPException(
                404, f"stage {j}: study {study_id} has {len(done)} finished stage(s)"
            )
        return done[j]
    for s in stages:
        if s.stage_index == j:
            return s
    raise HTTPException(404, f"stage {j} of study {study_id} not found")


# ---------------------------------------------------------------------------- posteriors


def parameter_summaries(
    X: NDArray[np.float64],
    names: Sequence[str],
    units: dict[str, str | None],
    log_prior: NDArray[np.float64] | None = None,
    log_likelihood: NDArray[np.float64] | None = None,
) -> tuple[list[ParameterSummary], list[list[float | None]], Any]:
    """Per-parameter summaries, the correlation matrix and the PosteriorSummary."""
    post = summarize(X, names, log_prior, log_likelihood)
    ci = np.atleast_2d(credible_interval(X, 0.95))
    params = []
    for k, name in enumerate(names):
        params.append(
            ParameterSummary(
                name=name,
                unit=units.get(name),
                mean=finite_or_none(post.mean[k]),
                sd=finite_or_none(post.sd[k]),
                quantiles={
                    f"q{100 * q:g}": finite_or_none(v)
                    for q, v in zip(post.quantile_levels, post.quantiles[:, k], strict=True)
                },
                ci95=[finite_or_none(ci[k, 0]), finite_or_none(ci[k, 1])],
                map=None if post.map_sample is None else finite_or_none(post.map_sample[k]),
            )
        )
    corr = [[finite_or_none(v) for v in row] for row in np.asarray(post.correlation)]
    return params, corr, post


def agreement_of(
    chains: NDArray[np.float64], names: list[str], studies: Sequence[StudyRecord]
) -> AgreementOut | None:
    """R-hat, ESS and the verdict of studies' (equally sized) final populations ``chains``
    (K, n, d), each one chain (:mod:`scm_core.calibration.convergence`); None for one study."""
    if chains.shape[0] < 2:
        return None
    z = [math.nan if s.log_evidence is None else s.log_evidence for s in studies]
    se = [math.sqrt(s.log_evidence_var) if s.log_evidence_var else 0.0 for s in studies]
    v = diagnose_runs(names, list(chains), z, se)
    sd, _ = v.log_evidence_spread
    return AgreementOut(
        studies=v.runs,
        draws_per_study=v.draws_per_run,
        rhat_limit=RHAT_LIMIT,
        converged=v.converged,
        disagreeing=list(v.disagreeing),
        few_effective=list(v.few_effective),
        verdict=v.line(),
        parameters={
            p.name: ParameterAgreementOut(
                rhat=finite_or_none(p.rhat),
                ess_bulk=finite_or_none(p.ess_bulk),
                ess_tail=finite_or_none(p.ess_tail),
                study_means=list(p.run_means),
            )
            for p in v.parameters
        },
        log_evidence_sd=finite_or_none(sd),
    )
