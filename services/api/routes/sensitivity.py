"""Sensitivity studies: Morris screening of the SCM soil parameters (paper section 4.4).

A sensitivity study is a study of the screening kind (:mod:`services.studies.kinds.screening`):
its design points run as work batches like TMCMC chains (locally or on Celery workers) and the
Morris analysis is stored when the last batch is in. Cancel it with ``POST /studies/{id}/cancel``;
its design points and steady F, T, z are the samples of its stage 0
(``GET /studies/{id}/stages/0/samples.csv``).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response

from scm_core.calibration import MorrisSettings
from services.limits import INT64_MAX
from services.store import Store, StudyRecord
from services.studies import base_case, create_and_start, sensitivity_spec
from services.studies.kinds.screening import KIND as SCREENING

from ..deps import DispatcherDep, SettingsDep, StoreDep, require_read, require_write
from ..etags import etag_of, not_modified, set_etag
from ..params import StudyId, parse_statuses, status_query
from ..schemas import SensitivityCreate, SensitivityOut, SensitivityPage
from ..views import page_out, sensitivity_out
from . import errors

router = APIRouter(
    prefix="/sensitivity", tags=["sensitivity"], dependencies=[Depends(require_read)]
)


def _get(store: Store, study_id: int) -> StudyRecord:
    study = store.studies.get(study_id)
    if study.kind != SCREENING.name:
        raise HTTPException(
            404, f"sensitivity study {study_id} not found (study {study_id} is a calibration)"
        )
    return study


@router.post(
    "",
    response_model=SensitivityOut,
    status_code=201,
    summary="Submit a Morris sensitivity study",
    dependencies=[Depends(require_write)],
    responses=errors(401, 413, 422),
)
def create_sensitivity(
    body: SensitivityCreate,
    response: Response,
    store: StoreDep,
    dispatcher: DispatcherDep,
    settings: SettingsDep,
) -> SensitivityOut:
    """Screen the 7 soil parameters of Table 1 (k_c and k_phi jointly through k*, eq. 11,
    unless ``separate_k``) with r Morris trajectories under the test conditions of
    ``dataset_id``, with the case's nominal values and simulator settings. Bounds: ``bounds``,
    else the case's prior for a calibrated factor, else the defaults (Table 2 for n, phi, J).
    Any problem answers 422 naming the field, and nothing is stored."""
    spec = sensitivity_spec(
        store,
        settings,
        base_case(body.preset, body.case),
        body.dataset_id,
        MorrisSettings(body.r, body.levels, body.seed, not body.separate_k, body.bounds),
        batch_size=body.batch_size,
        name=body.name,
    )
    study_id = create_and_start(store, spec, dispatcher)
    response.headers["Location"] = f"/sensitivity/{study_id}"
    return sensitivity_out(store, store.studies.get(study_id))


@router.get(
    "",
    response_model=SensitivityPage,
    summary="List sensitivity studies",
    responses=errors(401, 422),
)
def list_sensitivity(
    store: StoreDep,
    status: Annotated[str | None, status_query("sensitivity studies")] = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
) -> SensitivityPage:
    """Sensitivity studies, newest first, with their results."""
    statuses = parse_statuses(status)
    page = store.studies.list(statuses, kind=SCREENING.name, limit=limit, offset=offset)
    return page_out(SensitivityPage, page, lambda s: sensitivity_out(store, s))


@router.get(
    "/{study_id}",
    response_model=SensitivityOut,
    summary="A sensitivity study: progress and Morris statistics",
    responses=errors(401, 404),
)
def get_sensitivity(
    study_id: StudyId, request: Request, response: Response, store: StoreDep
) -> SensitivityOut:
    """The design (factors, bounds, r, levels), the progress block (evaluations are design
    points) and, once completed, the Morris statistics: mu, mu*, sigma and the normalised
    linear (mu* / sum mu*) and non-linear (sigma / sum sigma) indices of Figure 4, per
    response F [N], T [N m], z [m]. 304 for an unchanged study's ETag."""
    tag = etag_of("sensitivity", study_id, store.studies.version(study_id))
    if (unchanged := not_modified(request, tag)) is not None:
        return unchanged  # type: ignore[return-value]
    study = _get(store, study_id)
    set_etag(response, tag)
    return sensitivity_out(store, study)
