"""Studies of every kind: list, progress, cancel, stages, samples, summary, events.

Submitting one is its kind's route (``POST /studies`` is the calibration kind's, mounted with
every kind's by :mod:`.kinds`).
"""

from __future__ import annotations

import csv
import io
import logging
import math
from collections.abc import Iterator
from typing import Annotated, Any

from fastapi import APIRouter, Body, Depends, HTTPException, Query, Request, Response
from fastapi.responses import StreamingResponse

from scm_core.jsondoc import finite_or_none
from services.limits import (
    INT64_MAX,
)
from services.store import Store
from services.studies import (
    StudyRequestError,
)
from services.studies.kinds import KINDS, kind_of

from ..deps import SettingsDep, StoreDep, require_read, require_write, token_ok
from ..etags import etag_of, not_modified, set_etag
from ..params import StageIndex, StudyId, parse_statuses, status_query
from ..schemas import (
    CancelRequest,
    EventOut,
    SamplesPage,
    StageOut,
    StudyOut,
    StudyPage,
    SummaryOut,
)
from ..views import (
    named_responses,
    num_list,
    page_out,
    parameter_names,
    parameter_summaries,
    parameter_units,
    resolve_stage,
    response_names,
    stage_out,
    study_brief,
    study_out,
)
from . import errors

log = logging.getLogger(__name__)

router = APIRouter(prefix="/studies", tags=["studies"], dependencies=[Depends(require_read)])

SAMPLE_PAGE_MAX = 5000
CSV_CHUNK = 2000


# ---------------------------------------------------------------------------- reading


@router.get("", response_model=StudyPage, summary="List studies", responses=errors(401, 422))
def list_studies(
    request: Request,
    response: Response,
    store: StoreDep,
    status: Annotated[str | None, status_query("studies")] = None,
    kind: Annotated[
        str | None,
        Query(
            max_length=16,
            description="Filter by kind: calibration, sensitivity, update, prediction (the names "
            "before migration 0011, tmcmc and morris, are refused naming these)",
            json_schema_extra={"enum": sorted(KINDS)},
        ),
    ] = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
) -> StudyPage:
    """Studies of all kinds, newest first. The ETag changes when a study of the page changes
    or the page's membership does: ``If-None-Match`` gets 304 otherwise."""
    statuses = parse_statuses(status)
    if kind is not None and kind not in KINDS:
        raise StudyRequestError(f"query.kind: unknown study kind {kind!r}; one of {sorted(KINDS)}")
    versions = store.studies.list_versions(statuses, kind=kind, limit=limit, offset=offset)
    tag = etag_of("studies", statuses, kind, limit, offset, versions)
    if (unchanged := not_modified(request, tag)) is not None:
        return unchanged  # type: ignore[return-value]
    set_etag(response, tag)
    page = store.studies.list(statuses, kind=kind, limit=limit, offset=offset)
    return page_out(StudyPage, page, study_brief)


@router.get(
    "/{study_id}",
    response_model=StudyOut,
    summary="A study with its progress",
    responses=errors(401, 404),
)
def get_study(study_id: StudyId, request: Request, response: Response, store: StoreDep) -> StudyOut:
    """The study, its case document and a progress block: current stage and exponent,
    evaluations done and planned in it, model runs so far, rate and ETA of the stage. With the
    ETag of an unchanged study in ``If-None-Match``: 304 (rate and ETA as of its last change)."""
    tag = etag_of("study", study_id, store.studies.version(study_id))
    if (unchanged := not_modified(request, tag)) is not None:
        return unchanged  # type: ignore[return-value]
    set_etag(response, tag)
    return study_out(store, store.studies.get(study_id))


@router.post(
    "/{study_id}/cancel",
    response_model=StudyOut,
    summary="Cancel a study",
    dependencies=[Depends(require_write)],
    responses=errors(401, 404, 409),
)
def cancel_study(
    study_id: StudyId, store: StoreDep, body: Annotated[CancelRequest | None, Body()] = None
) -> StudyOut:
    """Cancel a queued or running study (work in flight is abandoned); 409 if it has ended."""
    if not store.studies.cancel(study_id, body.reason if body else None):
        study = store.studies.get(study_id)
        raise HTTPException(
            409,
            f"study {study_id} is {study.status}: only queued or running studies can be cancelled",
        )
    return study_out(store, store.studies.get(study_id))


@router.get(
    "/{study_id}/stages",
    response_model=list[StageOut],
    summary="Stages and their diagnostics",
    responses=errors(401, 404),
)
def list_stages(
    study_id: StudyId, request: Request, response: Response, store: StoreDep
) -> list[StageOut]:
    """Every stage so far with its diagnostics; 304 for an unchanged study's ETag."""
    tag = etag_of("stages", study_id, store.studies.version(study_id))
    if (unchanged := not_modified(request, tag)) is not None:
        return unchanged  # type: ignore[return-value]
    set_etag(response, tag)
    return [stage_out(store, s) for s in store.stages.list(study_id)]


@router.get(
    "/{study_id}/stages/{stage}/samples",
    response_model=SamplesPage,
    summary="Samples of a stage (JSON pages)",
    responses=errors(401, 404, 409),
)
def get_samples(
    study_id: StudyId,
    stage: StageIndex,
    store: StoreDep,
    offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
    limit: Annotated[int, Query(ge=1, le=SAMPLE_PAGE_MAX)] = 500,
) -> SamplesPage:
    """Rows ``offset`` .. ``offset + limit - 1`` of stage ``stage`` (-1: the last finished
    stage). Non-finite numbers are the strings "nan", "inf", "-inf". A stage that is not
    finished has no samples yet (total 0)."""
    st = resolve_stage(store, study_id, stage)
    study = store.studies.get(study_id)
    page = store.samples.page(study_id, st.stage_index, start=offset, limit=limit)
    a = page.arrays
    has_resp = a.responses is not None and len(a) > 0
    responses, rnames = (
        named_responses(a.responses, response_names(store, study)) if has_resp else (None, [])
    )
    return SamplesPage(
        study_id=study_id,
        stage=st.stage_index,
        stage_status=st.status,
        total=page.total,
        limit=limit,
        offset=offset,
        next_offset=page.next_start,
        names=parameter_names(study),
        response_names=rnames if has_resp else None,
        samples=num_list(a.samples) if len(a) else [],
        log_likelihood=num_list(a.log_likelihood),
        log_prior=num_list(a.log_prior),
        responses=num_list(responses) if has_resp else None,
    )


def _csv_chunks(store: Store, study_id: int, stage: int, names: list[str], rnames: list[str]):
    first = store.samples.page(study_id, stage, start=0, limit=CSV_CHUNK)
    with_resp = first.arrays.responses is not None and len(first.arrays) > 0
    if with_resp:
        _, rnames = named_responses(first.arrays.responses, rnames)

    def render(rows: list[list[Any]]) -> str:
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows(rows)
        return buf.getvalue()

    def gen() -> Iterator[str]:
        yield render(
            [["sample", *names, "log_likelihood", "log_prior", *(rnames if with_resp else [])]]
        )
        page = first
        while len(page.arrays):
            a = page.arrays
            R = named_responses(a.responses, rnames)[0] if a.responses is not None else None
            rows = []
            for i in range(len(a)):
                row: list[Any] = [page.start + i, *a.samples[i].tolist()]
                row += [float(a.log_likelihood[i]), float(a.log_prior[i])]
                if with_resp and R is not None:
                    row += R[i].tolist()
                rows.append(row)
            yield render(rows)
            if page.next_start is None:
                break
            page = store.samples.page(study_id, stage, start=page.next_start, limit=CSV_CHUNK)

    return gen()


@router.get(
    "/{study_id}/stages/{stage}/samples.csv",
    summary="Samples of a stage (streamed CSV)",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/csv": {}}}, **errors(401, 404, 409)},
)
def get_samples_csv(study_id: StudyId, stage: StageIndex, store: StoreDep) -> StreamingResponse:
    """All samples of stage ``stage`` (-1: the last finished one) as CSV: sample index,
    parameters, log_likelihood, log_prior, responses. Floats round-trip exactly; non-finite
    values are written nan, inf, -inf."""
    st = resolve_stage(store, study_id, stage)
    study = store.studies.get(study_id)
    chunks = _csv_chunks(
        store, study_id, st.stage_index, parameter_names(study), response_names(store, study)
    )
    filename = f"study{study_id}_stage{st.stage_index}_samples.csv"
    return StreamingResponse(
        chunks,
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )


@router.get(
    "/{study_id}/inference-data",
    summary="The calibration as an ArviZ InferenceData file (NetCDF)",
    response_class=Response,
    responses={
        200: {"content": {"application/x-netcdf": {}}, "description": "An InferenceData file."},
        **errors(401, 404, 409),
    },
)
def get_inference_data(
    study_id: StudyId,
    request: Request,
    store: StoreDep,
    group: Annotated[
        bool, Query(description="Every run of the study's run group, one chain each.")
    ] = False,
) -> Response:
    """The last finished stage as ``posterior`` (one chain; with ``group`` and a study of a
    run group, one chain per run, their agreement in the attributes), stage 0 as ``prior``,
    ``sample_stats``, ``observed_data`` (the datasets' steady means and standard errors, SI)
    and ``tempering`` (per stage), as ``scm-calib export --to netcdf`` writes it;
    ``arviz.from_netcdf`` reads it. 409 for a study of another kind or without a finished
    tempering stage. ETag: the studies' versions (304 when none changed)."""
    study = store.studies.get(study_id)
    ids = [study_id]
    if group and study.run_group is not None:
        ids = store.studies.run_group(study.run_group)
    versions = [store.studies.version(i) for i in ids]
    tag = etag_of("inference-data", ids, versions)
    if (unchanged := not_modified(request, tag)) is not None:
        return unchanged
    data = request.app.state.netcdf_cache.get(store, ids, versions)
    out = Response(
        data,
        media_type="application/x-netcdf",
        headers={"Content-Disposition": f'attachment; filename="study_{study_id}.nc"'},
    )
    set_etag(out, tag)
    return out


@router.get(
    "/{study_id}/summary",
    response_model=SummaryOut,
    summary="Posterior summary of the last finished stage",
    responses=errors(401, 404, 409),
)
def get_summary(study_id: StudyId, store: StoreDep) -> SummaryOut:
    """Mean, sd, quantiles, 95 % interval, correlations and MAP sample of the last finished
    stage (the posterior when ``is_posterior``: exponent 1), with the log evidence."""
    study = store.studies.get(study_id)
    kind = kind_of(study.kind)
    if not kind.posterior:
        raise HTTPException(
            409,
            f"study {study_id} is a {kind.title} study, whose stages do not temper to a "
            f"posterior: its result is at GET {kind.collection}/{study_id}",
        )
    st = resolve_stage(store, study_id, -1)
    a = store.samples.arrays(study_id, st.stage_index)
    if len(a) < 2:
        raise HTTPException(409, f"study {study_id}: stage {st.stage_index} has < 2 samples")
    names = parameter_names(study)
    params, corr, post = parameter_summaries(
        a.samples, names, parameter_units(study), a.log_prior, a.log_likelihood
    )
    last = st.stage_index == max(s.stage_index for s in store.stages.list(study_id))
    var = study.log_evidence_var if (last and study.status not in ("queued", "running")) else None
    exponent = finite_or_none(st.exponent)
    return SummaryOut(
        study_id=study_id,
        status=study.status,
        stage=st.stage_index,
        exponent=exponent,
        is_posterior=exponent is not None and exponent >= 1.0 - 1e-12,
        n_samples=len(a),
        names=names,
        parameters=params,
        correlation=corr,
        map=None
        if post.map_sample is None
        else {n: finite_or_none(v) for n, v in zip(names, post.map_sample, strict=True)},
        map_log_posterior=finite_or_none(post.map_log_posterior),
        log_evidence=finite_or_none(st.log_evidence),
        log_evidence_sd=None if var is None or var < 0 else finite_or_none(math.sqrt(var)),
        model_runs=study.model_runs,
    )


@router.get(
    "/{study_id}/events",
    response_model=list[EventOut],
    summary="What happened to a study",
    responses=errors(401, 404),
)
def list_events(
    study_id: StudyId,
    request: Request,
    response: Response,
    store: StoreDep,
    settings: SettingsDep,
    after_id: Annotated[
        int | None, Query(ge=0, le=INT64_MAX, description="Only events after this id.")
    ] = None,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
) -> list[EventOut]:
    """The study's events in order (created, stage planned/done, cancelled, failed, ...);
    304 for an unchanged study's ETag (every event raises the study's version). Which worker
    ran a batch (its host and process) is shown only to callers with a valid token."""
    reveal = token_ok(request, settings)
    tag = etag_of("events", study_id, after_id, limit, reveal, store.studies.version(study_id))
    if (unchanged := not_modified(request, tag)) is not None:
        return unchanged  # type: ignore[return-value]
    set_etag(response, tag)
    events = store.events.list(study_id, after_id=after_id, limit=limit)
    return [
        EventOut(
            id=e.id,
            study_id=e.study_id,
            created_at=e.created_at,
            kind=e.kind,
            payload=e.payload if reveal else public_payload(e.payload),
        )
        for e in events
    ]


#: event payload keys that name a machine and a process (host names, pids)
PRIVATE_EVENT_KEYS = frozenset({"worker", "worker_id"})


def public_payload(payload: dict) -> dict:
    """An event's payload without the keys that name a host or a process."""
    return {k: v for k, v in payload.items() if k not in PRIVATE_EVENT_KEYS}
