"""Model comparison of completed calibrations of the same data: their model classes (runs of
one calibration each) ranked by log evidence over their runs, the best one's Bayes factors with
their uncertainty and a verdict (:func:`services.studies.comparable.compare_studies`)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Query

from services.store import NotFoundError, Store
from services.studies.comparable import compare_studies
from services.studies.kinds import kind_of

from ..deps import StoreDep, require_read
from ..params import parse_id_list
from ..schemas import BayesFactorOut, ComparisonOut, ModelClassOut
from . import errors
from .pooled import IDS_PATTERN

router = APIRouter(prefix="/comparison", tags=["comparison"], dependencies=[Depends(require_read)])


def comparison_of(store: Store, ids: list[int]) -> ComparisonOut:
    """The comparison of the studies ``ids``; HTTP 422 naming ``study_ids`` for anything but
    completed calibrations of the same data in at least two model classes."""
    if len(set(ids)) != len(ids):
        raise HTTPException(422, "study_ids: a study is listed twice")
    studies = []
    for sid in ids:
        try:
            study = store.studies.get(sid)
        except NotFoundError:
            raise HTTPException(422, f"study_ids: no study with id {sid}") from None
        kind = kind_of(study.kind)
        if not kind.posterior or study.status != "completed":
            raise HTTPException(
                422,
                f"study_ids: study {sid} is a {study.status} {kind.title} study, not a completed "
                "calibration",
            )
        studies.append(study)
    try:
        comparison, members = compare_studies(studies)
    except ValueError as exc:
        raise HTTPException(422, str(exc)) from None
    return ComparisonOut(
        classes=[
            ModelClassOut(
                name=m.name,
                study_ids=members[m.name],
                runs=m.runs,
                log_evidence=m.mean,
                se=m.se,
                spread=None if m.runs < 2 else m.spread,
                run_log_evidence=list(m.log_evidence),
            )
            for m in comparison.models
        ],
        bayes_factors=[BayesFactorOut(**bf.to_dict()) for bf in comparison.against_best],
    )


@router.get(
    "",
    response_model=ComparisonOut,
    summary="Model comparison of completed calibrations",
    responses=errors(401, 422),
)
def comparison_get(
    store: StoreDep,
    study_ids: Annotated[
        list[str],
        Query(
            description="Repeat the parameter, or give ids comma-separated: completed "
            "calibrations of the same data; runs of one calibration form one model class.",
            json_schema_extra={"items": {"type": "string", "pattern": IDS_PATTERN}},
        ),
    ],
) -> ComparisonOut:
    """The model classes ranked by the mean of their runs' log evidence (standard error from
    their spread), the best one's Bayes factor over each other with its 95 % interval and a
    verdict in words (Kass & Raftery 1995), 'not decided' when the interval includes 0. Reads
    only: needs a token only when reads do."""
    return comparison_of(store, parse_id_list(study_ids, "query.study_ids"))
