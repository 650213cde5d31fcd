"""The web dashboard: server-rendered pages (Jinja2) and htmx fragments over the store.

Pages (``/``, ``/ui/...``) are shells that hold no data and need no token; each loads its
content as fragments (``/ui/f/...``, read endpoints: they need the token when reads do) whose
requests ``static/dashboard.js`` sends with the token kept in the browser session. Live
fragments (a study's row, progress and stages) carry the study's ETag (``data-etag``) and poll
with ``If-None-Match`` every few seconds while the tab is visible and the study is active: an
unchanged study answers 304 from the studies table alone, and a study that has ended renders
without a polling trigger. Figures (``/ui/figures/...``) are SVG or PNG from
``services.plots``; a study's stage figures are also served as their charts' data (``.json``,
:mod:`services.plots.chart`), which the page draws (``static/charts.js``); all cached per
(study, stage, figure, options, format). Writes (cancel, upload, new study) go to the JSON API
from the page's script, with the token.
"""

from __future__ import annotations

import math
from importlib import resources
from typing import Annotated, Any

from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates

from scm_core.calibration import PRESETS, preset_cost
from scm_core.jsondoc import finite_or_none
from scm_core.signals.conditions import condition_unit
from scm_core.signals.responses import RESPONSES
from services.limits import INT64_MAX
from services.plots.choices import default_pairs
from services.plots.figures import FORMATS
from services.store import NotFoundError, Store, StudyRecord
from services.studies.comparable import compare_studies, why_not_runs
from services.studies.kinds import KINDS, posterior_kinds

from ..deps import StoreDep, require_read
from ..etags import etag_of, not_modified, set_etag
from ..params import DatasetId, StudyId, parse_id_list, parse_statuses
from ..routes.datasets import dataset_out
from ..views import (
    agreement_of,
    kind_posts,
    next_step_posts,
    parameter_names,
    parameter_summaries,
    parameter_units,
    predictions_of,
    stage_out,
    study_brief,
    study_progress,
)
from .compare_figures import compare, final_populations, ranks, runs_as_chains
from .study_figures import (
    CHART_FORMAT,
    DRAW_SECONDS,
    MATRIX_MAX,
    FigureError,
    dataset_signals,
    default_matrix,
    study_figure,
)
from .text_filters import register as register_text_filters
from .warmer import FigureWarmer

__all__ = ["dashboard_router", "mount_static"]

PAGE_SIZE = 50
ACTIVE = ("queued", "running")
#: seconds between polls of a live fragment (the list's own poll is slower: new studies)
POLL_SECONDS = 1
LIST_POLL_SECONDS = 10


def _templates() -> Jinja2Templates:
    """The dashboard's templates, and the kinds' own where a kind brings them
    (``KindPanel.templates``)."""
    folder = resources.files("services.api.dashboard") / "templates"
    own = [str(k.panel.templates) for k in KINDS.values() if k.panel.templates is not None]
    t = Jinja2Templates(directory=[str(folder), *own])
    register_text_filters(t.env)
    t.env.globals.update(
        POLL_SECONDS=POLL_SECONDS,
        LIST_POLL_SECONDS=LIST_POLL_SECONDS,
        ACTIVE=ACTIVE,
        DRAW_SECONDS=DRAW_SECONDS,
        RESPONSES=RESPONSES,
        RESPONSE_UNITS={r.key: r.shown_in for r in RESPONSES},
        RESPONSE_SCALES={r.key: r.scale for r in RESPONSES},
    )
    return t


def mount_static(app: Any) -> None:
    """Serve ``static/`` (htmx, the page script and style) at ``/ui/static``."""
    folder = resources.files("services.api.dashboard") / "static"
    app.mount("/ui/static", StaticFiles(directory=str(folder)), name="dashboard-static")


#: figures whose URL names their content (a finished stage, a study version): kept for a year
FIXED_FIGURE_CACHE = "private, max-age=31536000, immutable"


def _figure_response(data: bytes, fmt: str, filename: str, fixed: bool = False) -> Response:
    """A figure; ``fixed``: its URL names what it shows (a finished stage, a study version),
    so the browser may keep it for good; otherwise for a minute."""
    return Response(
        data,
        media_type=FORMATS.get(fmt, "application/json"),
        headers={
            "Cache-Control": FIXED_FIGURE_CACHE if fixed else "private, max-age=60",
            "Content-Disposition": f'inline; filename="{filename}"',
        },
    )


def _fmt(fmt: str, chart: bool = False) -> str:
    """``fmt`` if it is an image format (or, with ``chart``, a chart's JSON), else 404."""
    known = sorted(FORMATS) + ([CHART_FORMAT] if chart else [])
    if fmt not in known:
        raise HTTPException(404, f"figure format must be one of {known}, got {fmt!r}")
    return fmt


def dashboard_router(warmer: FigureWarmer) -> APIRouter:
    """Pages, fragments and figures of the dashboard (not in the OpenAPI document); the figures
    go through ``warmer``'s cache, and a study's live fragments ask it to keep them drawn."""
    templates = _templates()
    router = APIRouter(include_in_schema=False)
    router.include_router(_page_routes(templates))
    router.include_router(_study_fragment_routes(templates, warmer))
    router.include_router(_other_fragment_routes(templates))
    router.include_router(_figure_routes(warmer))
    return router


def _reads() -> APIRouter:
    """A router of read endpoints: they need the token when reads do."""
    return APIRouter(include_in_schema=False, dependencies=[Depends(require_read)])


def _page(templates: Jinja2Templates, request: Request, name: str, **ctx: Any) -> HTMLResponse:
    return templates.TemplateResponse(request, name, ctx)


def _fragment(
    templates: Jinja2Templates, request: Request, name: str, tag: str | None = None, **ctx: Any
) -> Response:
    out = templates.TemplateResponse(request, name, {"etag": tag, **ctx})
    if tag is not None:
        set_etag(out, tag)
    return out


def _page_routes(templates: Jinja2Templates) -> APIRouter:
    """The pages: shells that hold no data and need no token."""
    pages = APIRouter(include_in_schema=False)

    @pages.get("/", response_class=HTMLResponse)
    def studies_page(
        request: Request,
        status: Annotated[str | None, Query(max_length=200)] = None,
        kind: Annotated[str | None, Query(max_length=16)] = None,
        offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
    ) -> HTMLResponse:
        return _page(
            templates,
            request,
            "studies.html",
            status=status or "",
            kind=kind or "",
            offset=offset,
            kinds=[(name, KINDS[name].title) for name in sorted(KINDS)],
            statuses=("queued", "running", "completed", "stalled", "failed", "cancelled"),
        )

    @pages.get("/ui/studies/{study_id}", response_class=HTMLResponse)
    def study_page(request: Request, study_id: StudyId) -> HTMLResponse:
        return _page(templates, request, "study.html", study_id=study_id)

    @pages.get("/ui/compare", response_class=HTMLResponse)
    def compare_page(
        request: Request,
        ids: Annotated[str | None, Query(max_length=400)] = None,
        id: Annotated[list[int] | None, Query(max_length=50)] = None,
    ) -> HTMLResponse:
        chosen = ",".join(filter(None, [ids or "", *(str(i) for i in id or [])]))
        return _page(templates, request, "compare.html", ids=chosen)

    @pages.get("/ui/datasets", response_class=HTMLResponse)
    def datasets_page(
        request: Request, offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0
    ) -> HTMLResponse:
        return _page(templates, request, "datasets.html", offset=offset)

    @pages.get("/ui/datasets/{dataset_id}", response_class=HTMLResponse)
    def dataset_page(request: Request, dataset_id: DatasetId) -> HTMLResponse:
        return _page(templates, request, "dataset.html", dataset_id=dataset_id)

    return pages


def _study_fragment_routes(templates: Jinja2Templates, warmer: FigureWarmer) -> APIRouter:
    """The studies list and a study's live fragments (ETag-versioned)."""
    reads = _reads()

    @reads.get("/ui/f/studies")
    def studies_fragment(
        request: Request,
        store: StoreDep,
        status: Annotated[str | None, Query(max_length=200)] = None,
        kind: Annotated[str | None, Query(max_length=16)] = None,
        offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
    ) -> Response:
        statuses = parse_statuses(status or None)
        kind = kind or None
        if kind is not None and kind not in KINDS:
            raise HTTPException(422, f"query.kind: unknown study kind {kind!r}")
        versions = store.studies.list_versions(statuses, kind=kind, limit=PAGE_SIZE, offset=offset)
        tag = etag_of("ui-studies", statuses, kind, offset, versions)
        if (unchanged := not_modified(request, tag)) is not None:
            return unchanged
        page_ = store.studies.list(statuses, kind=kind, limit=PAGE_SIZE, offset=offset)
        rows = [_row(store, s) for s in page_.items]
        return _fragment(
            templates,
            request,
            "_studies_table.html",
            tag,
            rows=rows,
            total=page_.total,
            offset=offset,
            limit=PAGE_SIZE,
            status=status or "",
            kind=kind or "",
        )

    @reads.get("/ui/f/studies/{study_id}/row")
    def study_row_fragment(request: Request, study_id: StudyId, store: StoreDep) -> Response:
        tag = etag_of("ui-row", study_id, store.studies.version(study_id))
        if (unchanged := not_modified(request, tag)) is not None:
            return unchanged
        return _fragment(
            templates, request, "_study_row.html", tag, row=_row(store, store.studies.get(study_id))
        )

    @reads.get("/ui/f/studies/{study_id}/live")
    def study_live_fragment(request: Request, study_id: StudyId, store: StoreDep) -> Response:
        warmer.watch(study_id)
        tag = etag_of("ui-live", study_id, store.studies.version(study_id))
        if (unchanged := not_modified(request, tag)) is not None:
            return unchanged
        study = store.studies.get(study_id)
        stages = [stage_out(store, s) for s in store.stages.list(study_id)]
        return _fragment(
            templates,
            request,
            "_study_live.html",
            tag,
            study=study_brief(study),
            progress=study_progress(store, study),
            stages=stages,
            kind_title=_title(study),
            kind=KINDS.get(study.kind),
            posterior=_posterior(study),
            parent=(study.payload or {}).get("update_of"),
            source=(study.payload or {}).get("study_id"),  # a prediction's posterior
            result=study.result,
            runs=[] if study.run_group is None else store.studies.run_group(study.run_group),
        )

    @reads.get("/ui/f/studies/{study_id}/results")
    def study_results_fragment(request: Request, study_id: StudyId, store: StoreDep) -> Response:
        study = store.studies.get(study_id)
        warmer.watch(study_id)
        # the results change when a stage finishes (the current stage moves on) or the study
        # ends, both on the study's row, and, once it has ended, with the predictions made
        # from its posterior
        predictions = predictions_of(store, study) if study.status == "completed" else []
        made = [(p.id, p.status) for p in predictions]
        tag = etag_of("ui-results", study_id, study.status, study.current_stage, made)
        if (unchanged := not_modified(request, tag)) is not None:
            return unchanged
        done_stages = [s for s in store.stages.list(study_id) if s.status == "done"]
        done = [s.stage_index for s in done_stages]
        finished = done[-1] if done else None
        ctx: dict[str, Any] = {
            "study": study_brief(study),
            "stage": finished,
            "exponent": finite_or_none(done_stages[-1].exponent) if done_stages else None,
            "stages_done": done,
            "summary": None,
            "pairs": [],
            "matrix": [],
            "names": [],
            "result": study.result,
            "kind": KINDS.get(study.kind),
            "predictions": [study_brief(p) for p in predictions],
            "predicted": next((p.id for p in predictions if p.status == "completed"), None),
        }
        if _posterior(study) and finished is not None:
            a = store.samples.arrays(study_id, finished)
            if len(a) >= 2:
                names = parameter_names(study)
                params, _, _ = parameter_summaries(
                    a.samples, names, parameter_units(study), a.log_prior, a.log_likelihood
                )
                ctx.update(
                    summary=params,
                    names=names,
                    pairs=default_pairs(names, 1),
                    matrix=default_matrix(names) if len(names) >= 2 else [],
                    matrix_max=MATRIX_MAX,
                )
        return _fragment(templates, request, "_study_results.html", tag, **ctx)

    return reads


def _other_fragment_routes(templates: Jinja2Templates) -> APIRouter:
    """The comparison, datasets and new-study fragments."""
    reads = _reads()

    @reads.get("/ui/f/compare")
    def compare_fragment(
        request: Request, store: StoreDep, ids: Annotated[str | None, Query(max_length=400)] = None
    ) -> Response:
        chosen = _parse_ids(ids)
        completed = [
            s
            for k in posterior_kinds()
            for s in store.studies.list("completed", kind=k, limit=500).items
        ]
        completed.sort(key=lambda s: -s.id)
        studies, waiting = [], []
        for sid in chosen:
            try:
                st = store.studies.get(sid)
            except NotFoundError:
                raise HTTPException(422, f"ids: no study with id {sid}") from None
            if _posterior(st) and st.status in ("queued", "running"):
                waiting.append(st)  # shown as running; compared once it completes
                continue
            if not _posterior(st) or st.status != "completed":
                raise HTTPException(
                    422,
                    f"ids: study {sid} is a {st.status} {_title(st)}, not a completed calibration",
                )
            studies.append(st)
        ctx: dict[str, Any] = {
            "completed": completed,
            "chosen": chosen,
            "rows": [],
            "table": [],
            "waiting": waiting,
        }
        if len(studies) >= 2:
            ctx.update(_comparison(store, studies))
        return _fragment(templates, request, "_compare.html", None, **ctx)

    @reads.get("/ui/f/datasets")
    def datasets_fragment(
        request: Request,
        store: StoreDep,
        offset: Annotated[int, Query(ge=0, le=INT64_MAX)] = 0,
    ) -> Response:
        page_ = store.datasets.list(limit=PAGE_SIZE, offset=offset)
        items = [dataset_out(d) for d in page_.items]
        return _fragment(
            templates,
            request,
            "_datasets_table.html",
            None,
            items=items,
            # a steered wheel's lateral force only where a dataset of the page has it
            responses=[
                r for r in RESPONSES if not r.steered or any(r.key in d.means for d in items)
            ],
            total=page_.total,
            offset=offset,
            limit=PAGE_SIZE,
        )

    @reads.get("/ui/f/datasets/{dataset_id}")
    def dataset_fragment(request: Request, dataset_id: DatasetId, store: StoreDep) -> Response:
        d = dataset_out(store.datasets.get(dataset_id))
        units = {k: condition_unit(k) for k in d.conditions}
        return _fragment(templates, request, "_dataset.html", None, d=d, units=units)

    @reads.get("/ui/f/studies/{study_id}/next")
    def next_steps_fragment(request: Request, study_id: StudyId, store: StoreDep) -> Response:
        """Forms that start from a completed calibration: an update, a prediction."""
        study = store.studies.get(study_id)
        datasets = store.datasets.list(limit=200).items
        return _fragment(
            templates,
            request,
            "_study_next.html",
            None,
            s=study_brief(study),
            used=set(study.dataset_ids),
            datasets=datasets,
            **next_step_posts(),
        )

    @reads.get("/ui/f/presets")
    def new_study_fragment(request: Request, store: StoreDep) -> Response:
        datasets = store.datasets.list(limit=200).items
        presets = [
            {"name": k, "description": p.description, "cost": preset_cost(k).text()}
            for k, p in PRESETS.items()
        ]
        ctx = {"presets": presets, "datasets": datasets, "posts": kind_posts()}
        return _fragment(templates, request, "_new_study.html", None, **ctx)

    return reads


def _figure_routes(warmer: FigureWarmer) -> APIRouter:
    """Figures (SVG or PNG; a study's stage figures also as chart data, JSON) of studies,
    datasets and comparisons (in ``warmer``'s cache; study figures made by its drawing
    process)."""
    reads = _reads()
    cache = warmer.cache

    @reads.get("/ui/figures/studies/{study_id}/{name}.{fmt}")
    def study_figure_route(
        study_id: StudyId,
        name: str,
        fmt: str,
        store: StoreDep,
        stage: Annotated[int | None, Query(ge=0, le=10_000)] = None,
        a: Annotated[str | None, Query(max_length=40)] = None,
        b: Annotated[str | None, Query(max_length=40)] = None,
        p: Annotated[
            str | None,
            Query(max_length=400, description="A pair matrix's parameters, comma-separated."),
        ] = None,
        v: Annotated[
            int | None,
            Query(ge=0, le=INT64_MAX, description="The study version the figure is of."),
        ] = None,
    ) -> Response:
        fmt = _fmt(fmt, chart=True)
        study = store.studies.get(study_id)
        # a finished stage's figure never changes; one of another version is not served
        fixed = stage is not None or (v is not None and v == study.version)
        pair = (a, b) if a and b else None
        try:
            data = study_figure(
                store,
                study,
                name,
                fmt,
                cache,
                stage=stage,
                pair=pair,
                params=_names(p),
                drawer=warmer.drawer,
            )
        except FigureError as exc:
            raise HTTPException(404, str(exc)) from None
        suffix = f"_stage{stage}" if stage is not None else ""
        return _figure_response(data, fmt, f"study{study_id}_{name}{suffix}.{fmt}", fixed)

    @reads.get("/ui/figures/datasets/{dataset_id}/signals.{fmt}")
    def dataset_figure_route(dataset_id: DatasetId, fmt: str, store: StoreDep) -> Response:
        fmt = _fmt(fmt, chart=True)
        try:
            data = dataset_signals(store, dataset_id, fmt, cache)
        except ValueError as exc:
            raise HTTPException(404, str(exc)) from None
        return _figure_response(data, fmt, f"dataset{dataset_id}_signals.{fmt}")

    @reads.get("/ui/figures/{name}.{fmt}")
    def studies_figure_route(
        name: str, fmt: str, store: StoreDep, ids: Annotated[str, Query(max_length=400)]
    ) -> Response:
        """A figure of several studies: ``compare`` (their posteriors and pool, Figure 9) or
        ``ranks`` (rank plots of runs of one case)."""
        draw = {"compare": compare, "ranks": ranks}.get(name)
        if draw is None:
            raise HTTPException(404, "figure: one of compare, ranks")
        fmt = _fmt(fmt)
        chosen = _parse_ids(ids)
        studies = [store.studies.get(i) for i in chosen]
        if len(studies) < 2:
            raise HTTPException(422, "ids: choose at least two completed studies")
        try:
            data = draw(store, studies, fmt, cache)
        except FigureError as exc:
            raise HTTPException(404, str(exc)) from None
        return _figure_response(data, fmt, f"{name}_{'_'.join(map(str, chosen))}.{fmt}")

    return reads


def _names(text: str | None) -> tuple[str, ...] | None:
    """A comma-separated list of parameter names (None if empty)."""
    names = tuple(n.strip() for n in (text or "").split(",") if n.strip())
    return names or None


def _title(study: StudyRecord) -> str:
    """What a study of its kind is called (its kind's name for a kind this server lacks)."""
    kind = KINDS.get(study.kind)
    return study.kind if kind is None else kind.title


def _posterior(study: StudyRecord) -> bool:
    """Whether the study's stages temper to a posterior (its kind's ``posterior``)."""
    kind = KINDS.get(study.kind)
    return kind is not None and kind.posterior


def _row(store: Store, study: StudyRecord) -> dict[str, Any]:
    return {
        "study": study_brief(study),
        "progress": study_progress(store, study),
        "kind_title": _title(study),
        "case": str((study.case or {}).get("name") or "–"),
        "active": study.status in ACTIVE,
        "etag": etag_of("ui-row", study.id, study.version),
    }


def _parse_ids(ids: str | None) -> list[int]:
    """The distinct study ids of the comparison's ``ids`` (comma-separated), in order."""
    return list(dict.fromkeys(parse_id_list([ids], "ids"))) if ids else []


def _comparison(store: Store, studies: list[StudyRecord]) -> dict[str, Any]:
    """Log evidences and Bayes factors against the best-supported study, and the shared
    parameters' posterior means and 95 % intervals per study."""
    rows = []
    best = max(
        (s for s in studies if s.log_evidence is not None),
        key=lambda s: s.log_evidence or -math.inf,
        default=None,
    )
    for s in studies:
        var = s.log_evidence_var
        ln_b = None
        if best is not None and s.log_evidence is not None:
            ln_b = best.log_evidence - s.log_evidence
        rows.append(
            {
                "study": s,
                "log_evidence": s.log_evidence,
                "log_evidence_sd": None if var is None or var < 0 else math.sqrt(var),
                "ln_bayes_factor": ln_b,
                "bayes_factor": None if ln_b is None else _safe_exp(ln_b),
            }
        )
    per: dict[int, dict[str, Any]] = {}
    shared: list[str] | None = None
    finals = final_populations(store, studies)
    for s, samples in zip(studies, finals or [], strict=False):
        names = parameter_names(s)
        params, _, _ = parameter_summaries(samples, names, parameter_units(s))
        per[s.id] = {p.name: p for p in params}
        shared = names if shared is None else [n for n in shared if n in names]
    # the runs' agreement (R-hat across them), on equal subsamples as /pooled takes them; only
    # of runs of one calibration (two different calibrations "not converging" means nothing)
    not_runs = why_not_runs(studies)
    chains = None if not_runs else runs_as_chains(studies, finals)
    agreement = None if chains is None else agreement_of(chains[1], chains[0], studies)
    table = [
        {"name": n, "cells": [per[s.id][n] for s in studies], "unit": per[studies[0].id][n].unit}
        for n in shared or []
    ]
    same_data = len({tuple(sorted(s.dataset_ids)) for s in studies}) == 1
    classes, why_no_classes = None, None
    if same_data and not_runs is not None:  # runs of one calibration: their agreement above
        try:
            classes = compare_studies(studies)[0]
        except ValueError as exc:
            why_no_classes = str(exc).removeprefix("study_ids: ")
    return {
        "classes": classes,
        "why_no_classes": why_no_classes,
        "agreement": agreement,
        "not_runs": not_runs,
        "rows": rows,
        "best": best,
        "table": table,
        "studies": studies,
        "shared": shared,
        "same_data": same_data,
    }


def _safe_exp(x: float) -> float:
    return math.exp(x) if x < 700 else math.inf
