"""Pooled posterior of several completed studies with the same parameters (paper Fig. 9).

Each study's final stage is an equally weighted posterior sample; pooling takes the same number
of samples from each (``scm_core.inference.posterior.pool_samples``), so every study weighs the
same whatever its size. With two or more studies (e.g. one case run with several seeds, the
paper's three repetitions) ``agreement`` gives per parameter ArviZ's rank-normalised split
R-hat and bulk/tail ESS across them (each study's subsample one chain) and a verdict
(:mod:`scm_core.calibration.convergence`).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from fastapi import APIRouter, Depends, HTTPException, Query

from scm_core.inference.posterior import pool_samples
from scm_core.jsondoc import finite_or_none
from scm_core.seeds import SEED_MAX
from services.store import NotFoundError, Store
from services.studies.kinds import kind_of

from ..deps import StoreDep, require_read
from ..params import parse_id_list
from ..schemas import COUNT_MAX, PooledOut, PooledRequest, PooledStudy
from ..views import (
    agreement_of,
    parameter_names,
    parameter_summaries,
    parameter_units,
    resolve_stage,
)
from . import errors

router = APIRouter(prefix="/pooled", tags=["pooled"], dependencies=[Depends(require_read)])


#: one ``study_ids`` item of the query form: at least one id; ids separated by commas, spaces
#: around them and empty items ignored
IDS_PATTERN = r"^(?: *,)* *[0-9]+ *(?:, *(?:[0-9]+ *)?)*$"


def _unprocessable(message: str) -> HTTPException:
    return HTTPException(422, message)


def pooled_summary(store: Store, req: PooledRequest) -> PooledOut:
    ids = list(req.study_ids)
    if not ids:
        raise _unprocessable("study_ids: give at least one completed study")
    if len(set(ids)) != len(ids):
        raise _unprocessable("study_ids: a study is listed twice")
    studies, finals = [], []
    names: list[str] | None = None
    for sid in ids:
        try:
            study = store.studies.get(sid)
        except NotFoundError:
            raise _unprocessable(f"study_ids: no study with id {sid}") from None
        kind = kind_of(study.kind)
        if not kind.posterior:
            raise _unprocessable(
                f"study_ids: study {sid} is a {kind.title} study, not a calibration (it has no "
                "posterior)"
            )
        if study.status != "completed":
            raise _unprocessable(
                f"study_ids: study {sid} is {study.status}; only completed studies are pooled"
            )
        these = parameter_names(study)
        if names is None:
            names = these
        elif these != names:
            raise _unprocessable(
                f"study_ids: study {sid} calibrates {these}, study {ids[0]} {names}: pooling "
                "needs the same parameters in the same order"
            )
        stage = resolve_stage(store, sid, -1)
        studies.append(study)
        finals.append(store.samples.arrays(sid, stage.stage_index).samples)
    assert names is not None
    smallest = min(len(x) for x in finals)
    n_per = req.n_per_study or smallest
    if n_per > smallest:
        raise _unprocessable(
            f"n_per_study: {n_per} is more than the smallest study's {smallest} samples"
        )
    X = pool_samples(finals, n_per, req.seed)
    params, corr, _ = parameter_summaries(X, names, parameter_units(studies[0]))
    per_study = [
        PooledStudy(
            study_id=s.id,
            name=s.name,
            n_samples=len(x),
            log_evidence=finite_or_none(s.log_evidence),
            mean={n: finite_or_none(v) for n, v in zip(names, x.mean(axis=0), strict=True)},
            sd={n: finite_or_none(v) for n, v in zip(names, x.std(axis=0, ddof=1), strict=True)},
        )
        for s, x in zip(studies, finals, strict=True)
    ]
    return PooledOut(
        agreement=agreement_of(X.reshape(len(finals), n_per, -1), names, studies),
        study_ids=ids,
        n_per_study=n_per,
        n_samples=int(X.shape[0]),
        names=names,
        parameters=params,
        correlation=corr,
        studies=per_study,
        samples=np.asarray(X).tolist() if req.include_samples else None,
    )


@router.post(
    "",
    response_model=PooledOut,
    summary="Pooled posterior of completed studies",
    responses=errors(401, 422),
)
def pooled_post(body: PooledRequest, store: StoreDep) -> PooledOut:
    """Summary (mean, sd, quantiles, correlations) of the pooled final samples of completed
    studies with the same parameters, each study's mean and sd, and (two or more studies)
    their agreement: R-hat, ESS and a convergence verdict. Reads only: needs a token only when
    reads do."""
    return pooled_summary(store, body)


@router.get(
    "",
    response_model=PooledOut,
    summary="Pooled posterior (query form)",
    responses=errors(401, 422),
)
def pooled_get(
    store: StoreDep,
    study_ids: Annotated[
        list[str],
        Query(
            description="Repeat the parameter, or give ids comma-separated.",
            json_schema_extra={"items": {"type": "string", "pattern": IDS_PATTERN}},
        ),
    ],
    n_per_study: Annotated[int | None, Query(ge=2, le=COUNT_MAX)] = None,
    seed: Annotated[int, Query(ge=0, le=SEED_MAX)] = 0,
) -> PooledOut:
    ids = parse_id_list(study_ids, "query.study_ids")
    return pooled_summary(store, PooledRequest(study_ids=ids, n_per_study=n_per_study, seed=seed))
