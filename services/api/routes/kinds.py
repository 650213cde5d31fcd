"""Every study kind's part of the API, mounted the same way from its declaration (``KindHttp``,
see :mod:`services.studies.kinds.base`): ``POST PATH`` submits one (or, for a kind's repeated
runs, several), ``GET PATH`` lists them and ``GET PATH/{id}`` reads one with its result; a kind
that brings only its create route (``reads`` False) answers with the common study. A study of
any kind is also a study: cancel it, read its stages, samples and events under
``/studies/{id}``. This module knows no kind by name.
"""

# no ``from __future__ import annotations``: the routes' annotations are the kind's request
# and result models, which FastAPI must see as classes, not as names to resolve

from typing import Annotated, Any

from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response
from pydantic import BaseModel, create_model

from services.limits import INT64_MAX
from services.store import Store, StudyRecord, StudySpec
from services.studies import create_runs_and_start
from services.studies.kinds.base import KindHttp, StudyKind

from ..deps import DispatcherDep, SettingsDep, StoreDep, require_read, require_write
from ..etags import etag_of, not_modified, set_etag
from ..params import StudyId, parse_statuses, status_query
from ..schemas import KindStudyOut, KindStudyPage, PageInfo, StudyOut
from ..views import page_out, study_brief, study_out, study_progress
from . import errors


def _models(title: str, result: Any, fields: type[BaseModel] | None) -> tuple[Any, Any]:
    """The models of one study of a kind and of a page of them: the study with the kind's
    result (and its own ``fields``, named after the kind: "SensitivityOut")."""
    if fields is None:
        return KindStudyOut[result], KindStudyPage[result]
    name = "".join(w.capitalize() for w in title.split())
    one = create_model(f"{name}Out", __base__=(KindStudyOut[result], fields))
    page = create_model(f"{name}Page", __base__=PageInfo, items=(list[one], ...))
    return one, page


def kind_router(kind: StudyKind) -> APIRouter:
    """The router of ``kind``'s part of the API (``kind.http`` must be set): its create route
    and, unless it brings only that, its collection's reads."""
    http = kind.http
    if http is None:
        raise ValueError(f"study kind {kind.name!r} has no part of the API of its own")
    result_model = http.result if http.result is not None else dict[str, Any]
    out_model, page_model = _models(kind.title, result_model, http.fields)

    def out(store: Store, study: StudyRecord) -> Any:
        own = http.fields_of(study).model_dump() if http.fields_of is not None else {}
        return out_model(
            **study_brief(study).model_dump(),
            **own,
            payload=dict(study.payload or {}),
            progress=study_progress(store, study),
            result=study.result,
        )

    router = APIRouter(
        prefix=http.path, tags=[http.path.strip("/")], dependencies=[Depends(require_read)]
    )
    if http.reads:
        _create_route(router, kind, out_model, out, http.path)
        _read_routes(router, kind, out_model, page_model, out)
    else:
        _create_route(router, kind, StudyOut, study_out, "/studies")
    return router


def _specs(made: StudySpec | Any) -> list[StudySpec]:
    """A kind's validated study, or its several, as a list."""
    return [made] if isinstance(made, StudySpec) else list(made)


def _create_route(
    router: APIRouter, kind: StudyKind, out_model: Any, out: Any, read_at: str
) -> None:
    """``POST PATH``: the kind's request, validated into its studies, stored and started;
    answered with ``out(store, first study)``, which is read at ``read_at/{id}``
    (``Location``)."""
    http: KindHttp = kind.http  # type: ignore[assignment]
    request_model = http.request

    @router.post(
        "",
        response_model=out_model,
        status_code=201,
        summary=http.summary or f"Submit a {kind.title}",
        description=http.description,
        dependencies=[Depends(require_write)],
        responses=errors(*http.statuses),
    )
    def create(
        body: request_model,
        response: Response,
        store: StoreDep,
        dispatcher: DispatcherDep,
        settings: SettingsDep,
    ) -> Any:
        specs = _specs(http.spec(store, settings, body))
        study_id = create_runs_and_start(store, specs, dispatcher)[0]
        response.headers["Location"] = f"{read_at}/{study_id}"
        return out(store, store.studies.get(study_id))


def _read_routes(
    router: APIRouter, kind: StudyKind, out_model: Any, page_model: Any, out: Any
) -> None:
    """``GET PATH`` (a page of the kind's studies) and ``GET PATH/{id}`` (one, with its
    result)."""
    plural = f"{kind.title}s"

    def get(store: Store, study_id: int) -> StudyRecord:
        study = store.studies.get(study_id)
        if study.kind != kind.name:
            raise HTTPException(
                404, f"{kind.title} {study_id} not found (study {study_id} is a {study.kind} study)"
            )
        return study

    @router.get(
        "",
        response_model=page_model,
        summary=f"List {plural}",
        responses=errors(401, 422),
    )
    def list_all(
        store: StoreDep,
        status: Annotated[str | None, status_query(plural)] = None,
        limit: Annotated[int, Query(ge=1, le=500)] = 50,
        offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
    ) -> Any:
        """Newest first, with their results."""
        page = store.studies.list(
            parse_statuses(status), kind=kind.name, limit=limit, offset=offset
        )
        return page_out(page_model, page, lambda s: out(store, s))

    @router.get(
        "/{study_id}",
        response_model=out_model,
        summary=f"A {kind.title}: progress and result",
        responses=errors(401, 404),
    )
    def read(study_id: StudyId, request: Request, response: Response, store: StoreDep) -> Any:
        """The study, the kind's settings (payload), progress and, once completed, its result;
        304 for an unchanged study's ETag."""
        tag = etag_of(kind.name, study_id, store.studies.version(study_id))
        if (unchanged := not_modified(request, tag)) is not None:
            return unchanged
        study = get(store, study_id)
        set_etag(response, tag)
        return out(store, study)
