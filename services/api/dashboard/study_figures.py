"""The dashboard's figures, made by ``services.plots`` from what the store holds.

Each figure is a function of stored, immutable data (a finished stage's samples, a completed
study's result, an uploaded log), so it is made once per (study, stage, figure, options,
format) and kept in a small in-memory LRU cache (:class:`FigureCache`); the schedule, which
grows with the study, is keyed by the study's version. Most are charts
(:mod:`services.plots.chart`): served as their data for the page to draw (``json``) or drawn by
matplotlib for a download (``svg``, ``png``); the others are matplotlib figures. Scatter layers
are thinned (``services.plots.posterior.pairs_chart``): a figure stays small whatever the
number of samples.
"""

from __future__ import annotations

import json
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

import services.plots as plots  # submodules (matplotlib) load when a figure is drawn
from scm_core.calibration import CaseDefinition, StudyModel
from scm_core.calibration.predict import Band, ConditionPrediction, ResponsePrediction
from scm_core.inference.posterior import map_sample
from scm_core.inference.priors import LOG_SCALE_KINDS
from scm_core.signals import SWTDataset
from scm_core.signals.responses import RESPONSE_KEYS
from services.plots.chart import Chart
from services.plots.choices import default_pairs, mean_b_eff
from services.store import StageRecord, Store, StudyRecord
from services.studies.datasets import load_datasets, stored_log
from services.studies.kinds import KINDS, KindPanel, kind_of, study_terms
from services.studies.kinds.base import stored_case

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "CHART_FORMAT",
    "STUDY_FIGURES",
    "FigureCache",
    "FigureError",
    "dataset_signals",
    "page_figures",
    "study_figure",
]


#: the format of a figure as chart data, drawn by the page's script (charts.js)
CHART_FORMAT = "json"


class FigureError(ValueError):
    """The figure cannot be drawn for this study or stage (the message says why)."""


class FigureCache:
    """A thread-safe LRU cache of rendered figures (bytes), of MAP simulations and of the
    finished stages' populations the figures share. A value being made is made once: a second
    caller of the same key waits for the first (a page's request during
    :class:`~services.api.dashboard.warmer.FigureWarmer`'s drawing, or two browsers), instead
    of drawing it again beside it."""

    def __init__(self, max_entries: int = 256) -> None:
        self.max_entries = max_entries
        self._items: OrderedDict[Hashable, Any] = OrderedDict()
        self._making: dict[Hashable, threading.Event] = {}
        self._lock = threading.Lock()

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def __contains__(self, key: Hashable) -> bool:
        with self._lock:
            return key in self._items

    def get_or_make(self, key: Hashable, make: Callable[[], Any]) -> Any:
        while True:
            with self._lock:
                if key in self._items:
                    self._items.move_to_end(key)
                    return self._items[key]
                busy = self._making.get(key)
                if busy is None:
                    self._making[key] = threading.Event()
                    break
            busy.wait()  # another thread is drawing it; if that failed, try ourselves
        try:
            value = make()  # outside the lock: figures take a while
            with self._lock:
                self._items[key] = value
                while len(self._items) > self.max_entries:
                    self._items.popitem(last=False)
            return value
        finally:
            with self._lock:
                self._making.pop(key).set()


@dataclass(frozen=True)
class StageData:
    names: list[str]
    samples: np.ndarray
    log_prior: np.ndarray
    log_likelihood: np.ndarray


def stage_data(store: Store, study: StudyRecord, stage: int, cache: FigureCache) -> StageData:
    """A finished stage's population, read once per ``cache`` (a figure process's): a page's
    charts read it five times (the fit's MAP, the pairs, the matrix, the trace, the prior and
    posterior), each read of 16,000 samples 30-50 ms (its rows fetched and decoded), 250 ms when
    a full garbage collection fell in it. A done stage's samples never change; the arrays are
    read-only, shared by the figures."""

    def read() -> StageData:
        a = store.samples.arrays(study.id, stage)
        if len(a) < 2:
            raise FigureError(f"stage {stage} of study {study.id} has fewer than 2 samples")
        names = study_terms(study).parameter_names or [f"x{k}" for k in range(a.samples.shape[1])]
        arrays = (a.samples, a.log_prior, a.log_likelihood)
        for x in arrays:
            x.flags.writeable = False
        return StageData(names, *arrays)

    return cache.get_or_make(("stage-data", study.id, stage), read)


def log_params(case: CaseDefinition) -> set[str]:
    return {n for n, d in case.prior().dists.items() if d.kind in LOG_SCALE_KINDS}


def _map(data: StageData) -> np.ndarray:
    return map_sample(data.samples, data.log_prior, data.log_likelihood)[0]


def _plot_datasets(store: Store, case: CaseDefinition, ids: Sequence[int]) -> list[SWTDataset]:
    """The study's datasets as the likelihood sees them, with the logs' series for drawing."""
    out = []
    for did, ds in zip(ids, load_datasets(store, case, ids), strict=True):
        if ds.source_kind == "timeseries":
            try:
                series = stored_log(store, did).series
            except ValueError:
                series = None
            out.append(ds if series is None else _with_series(ds, series))
        else:
            out.append(ds)
    return out


def _with_series(ds: SWTDataset, series: Any) -> SWTDataset:
    return replace(ds, series=series)


def map_simulations(
    store: Store, study: StudyRecord, stage: int, cache: FigureCache
) -> tuple[list[SWTDataset], list[Any], dict[str, float]]:
    """(datasets, simulations at the stage's MAP sample, measurement offsets), cached."""

    def make() -> tuple[list[SWTDataset], list[Any], dict[str, float]]:
        case = stored_case(study.case)
        data = stage_data(store, study, stage, cache)
        theta = _map(data)
        datasets = _plot_datasets(store, case, study.dataset_ids)
        model = StudyModel(case, datasets)
        sims = []
        for k in range(len(datasets)):
            try:
                sims.append(model.simulate_at(theta, k))
            except ValueError:
                sims.append(None)
        return datasets, sims, model.measurement_offsets(theta)

    return cache.get_or_make(("map-sims", study.id, stage), make)


# ---------------------------------------------------------------------------- study figures


def _schedule(store: Store, study: StudyRecord, stages: list[StageRecord], **_: Any) -> Chart:
    return plots.stages.schedule_chart(
        [s.stage_index for s in stages],
        [s.exponent for s in stages],
        [s.acceptance for s in stages],
        [s.ess for s in stages],
        study.n_samples,
        title=f"{study.name}: TMCMC schedule ({study.status})",
    )


def _trace(
    store: Store,
    study: StudyRecord,
    stage: int,
    cache: FigureCache,
    stages: Sequence[StageRecord],
    **_: Any,
) -> Chart:
    case = stored_case(study.case)
    done = [s.stage_index for s in stages if s.status == "done" and s.stage_index <= stage]
    data = [stage_data(store, study, j, cache) for j in done]
    return plots.stages.stage_trace_chart(
        data[-1].names,
        done,
        [d.samples for d in data],
        units=dict(case.prior().units or {}),
        log_params=log_params(case),
        title=f"{study.name}: population per stage, 0 to {stage} (median, 50 % and 95 %)",
    )


def _panel(study: StudyRecord) -> KindPanel:
    """How the study's kind is shown (its words for stage 0 and the last stage)."""
    return kind_of(study.kind).panel


def _stage_title(study: StudyRecord, stages: Sequence[StageRecord], stage: int) -> str:
    """ ", stage N" and, below exponent 1, what the samples are instead of a posterior."""
    p = next((s.exponent for s in stages if s.stage_index == stage), None)
    if stage == 0:
        return f", stage 0 ({_panel(study).stage_zero})"
    if p is not None and p < 1.0:
        return f", stage {stage} (exponent {p:.3g}: not a posterior)"
    return f", stage {stage}"


def _prior_posterior(
    store: Store,
    study: StudyRecord,
    stage: int,
    cache: FigureCache,
    stages: Sequence[StageRecord],
    **_: Any,
) -> Chart:
    case = stored_case(study.case)
    prior = case.prior()
    data = stage_data(store, study, stage, cache)
    first = stage_data(store, study, 0, cache)
    panel = _panel(study)
    return plots.posterior.prior_posterior_chart(
        data.names,
        first.samples,
        data.samples,
        bounds=prior.bounds,
        units=dict(prior.units or {}),
        map_sample=_map(data),
        reference=case.reference,
        title=f"{study.name}: {panel.start} and {panel.end}{_stage_title(study, stages, stage)}"
        " (Figure 5)",
        log_params=log_params(case),
        labels=(panel.start, panel.end),
    )


def _pairs(
    store: Store,
    study: StudyRecord,
    stage: int,
    cache: FigureCache,
    stages: Sequence[StageRecord],
    pair: tuple[str, str] | None = None,
    **_: Any,
) -> Chart:
    case = stored_case(study.case)
    data = stage_data(store, study, stage, cache)
    if pair is not None and not set(pair) <= set(data.names):
        raise FigureError(f"pair {pair[0]}, {pair[1]}: parameters are {', '.join(data.names)}")
    k_star_line = None
    k_star = case.reference.get("k_star")
    if (
        k_star
        and (pair is None or pair == ("k_c", "k_phi"))
        and {"k_c", "k_phi"} <= set(data.names)
    ):
        _, sims, _ = map_simulations(store, study, stage, cache)
        b_eff = mean_b_eff(sims[0])
        k_star_line = (k_star, b_eff) if b_eff else None
    chart = plots.posterior.pairs_chart(
        data.names,
        data.samples,
        pairs=None if pair is None else [pair],
        units=dict(case.prior().units or {}),
        reference=case.reference,
        k_star_line=k_star_line,
        title=f"{study.name}: bivariate density{_stage_title(study, stages, stage)} (Figures 6-8)",
        log_params=log_params(case),
    )
    if chart is None:
        raise FigureError(f"study {study.id} has no parameter pair to draw")
    return chart


#: at most this many parameters in a pair matrix (d * (d + 1) / 2 panels)
MATRIX_MAX = 6


#: what each of a stage's page charts takes to make, roughly [s] (medians of
#: ``benchmarks/bench_figures.py --fmt json``, a two-parameter study of two logs, one core): the
#: warmer makes them longest first and the page asks for them in the same order
#: (``data-cost``), so that its requests find them being made
DRAW_SECONDS = {
    "fit": 0.065,
    "pairs": 0.011,
    "matrix": 0.009,
    "trace": 0.008,
    "prior_posterior": 0.003,
    "schedule": 0.001,
}


def page_figures(names: Sequence[str], stage: int) -> list[dict[str, Any]]:
    """The figures a calibration's page shows for its last finished ``stage``, as keyword
    arguments of :func:`study_figure`, longest to draw first (the results fragment draws its
    links from the same defaults; :class:`~services.api.dashboard.warmer.FigureWarmer` draws
    them ahead of it)."""
    out: list[dict[str, Any]] = [
        {"name": "schedule"},
        {"name": "prior_posterior", "stage": stage},
        {"name": "trace", "stage": stage},
    ]
    out += [{"name": "pairs", "stage": stage, "pair": tuple(p)} for p in default_pairs(names, 1)]
    if len(names) >= 2:
        out.append({"name": "matrix", "stage": stage, "params": tuple(default_matrix(names))})
    out.append({"name": "fit", "stage": stage})
    return sorted(out, key=lambda f: -DRAW_SECONDS[f["name"]])


def default_matrix(names: Sequence[str]) -> list[str]:
    """The pair matrix's parameters unless chosen: those of the default pairs (the paper's),
    then the other physical parameters, at most four."""
    chosen: list[str] = []
    physical = [n for n in names if not n.startswith(("sigma_", "z_offset"))]
    for n in [*(n for p in default_pairs(names) for n in p), *physical]:
        if n not in chosen:
            chosen.append(n)
    return chosen[:4]


def _matrix(
    store: Store,
    study: StudyRecord,
    stage: int,
    cache: FigureCache,
    stages: Sequence[StageRecord],
    params: tuple[str, ...] | None = None,
    **_: Any,
) -> Chart:
    case = stored_case(study.case)
    data = stage_data(store, study, stage, cache)
    chosen = list(params) if params else default_matrix(data.names)
    unknown = [n for n in chosen if n not in data.names]
    if unknown:
        raise FigureError(f"p: {', '.join(unknown)} not among {', '.join(data.names)}")
    if not 2 <= len(chosen) <= MATRIX_MAX or len(set(chosen)) != len(chosen):
        raise FigureError(f"p: choose 2 to {MATRIX_MAX} different parameters")
    return plots.posterior.pair_matrix_chart(
        data.names,
        data.samples,
        chosen,
        units=dict(case.prior().units or {}),
        reference=case.reference,
        log_params=log_params(case),
        title=f"{study.name}: pair matrix{_stage_title(study, stages, stage)}",
    )


def _fit(
    store: Store,
    study: StudyRecord,
    stage: int,
    cache: FigureCache,
    stages: Sequence[StageRecord],
    **_: Any,
) -> Chart:
    """Measured vs simulated at the stage's MAP sample: each dataset's signals (Figure 3), or
    for a steered study (a dataset of known slip at a slip angle) the steady means against
    slip, a column per slip angle, with the prediction error's 95 % band at the MAP."""
    case = stored_case(study.case)
    datasets, sims, offsets = map_simulations(store, study, stage, cache)
    at = f"at the MAP{_stage_title(study, stages, stage)}"
    if not plots.fit.fits_against_slip(datasets):  # Figure 3 as it was
        return plots.fit.fit_chart(
            datasets,
            sims,
            title=f"{study.name}: measured vs simulated {at} (Figure 3)",
            responses=case.responses,
            offsets=offsets,
        )
    theta = _map(stage_data(store, study, stage, cache))
    sigmas = StudyModel(case, datasets).sigmas(theta)[0]
    return plots.fit.slip_fit_chart(
        datasets,
        sims,
        title=f"{study.name}: measured vs simulated steady means {at}, per slip angle",
        responses=case.responses,
        offsets=offsets,
        sigmas=dict(zip(case.responses, (float(x) for x in sigmas), strict=True)),
    )


def _indices(store: Store, study: StudyRecord, **_: Any) -> Figure:
    res = study.result or {}
    if "linear_index" not in res:
        raise FigureError(f"study {study.id} has no Morris result yet ({study.status})")
    title = f"{study.name}: Morris screening"
    return plots.sensitivity.stored_indices_figure(res, title, " (Figure 4)")


def _band(b: dict[str, Any] | None) -> Band | None:
    if b is None:
        return None
    return Band(*(np.nan if b[k] is None else float(b[k]) for k in ("median", "lo", "hi")))


def _predictions(store: Store, study: StudyRecord, **_: Any) -> Chart:
    res = study.result or {}
    if "predictions" not in res:
        raise FigureError(f"study {study.id} has no predictions yet ({study.status})")
    conds = [
        ConditionPrediction(
            name=c["name"],
            conditions=c["conditions"],
            slip_symmetric=c["slip_symmetric"],
            n_draws=c["n_draws"],
            n_failed=c["n_failed"],
            role=c["role"],
            responses={
                r: ResponsePrediction(
                    r, _band(v["simulated"]), _band(v.get("predictive")), v.get("measured")
                )
                for r, v in c["responses"].items()
            },
        )
        for c in res["predictions"]
    ]
    datasets = [c for c in conds if c.role != "sweep"]
    sweep = [c for c in conds if c.role == "sweep"]
    responses = [r for r in RESPONSE_KEYS if conds and r in conds[0].responses]
    return plots.predict.predictions_chart(
        datasets, sweep, title=f"{study.name}: posterior predictions", responses=responses
    )


#: figure name -> (builder, needs a finished stage); a kind names those it is drawn for
#: (``KindPanel.figures``)
STUDY_FIGURES: dict[str, tuple[Callable[..., Chart | Figure], bool]] = {
    "schedule": (_schedule, False),
    "prior_posterior": (_prior_posterior, True),
    "trace": (_trace, True),
    "pairs": (_pairs, True),
    "matrix": (_matrix, True),
    "fit": (_fit, True),
    "indices": (_indices, False),
    "predictions": (_predictions, False),
}


def study_figure(
    store: Store,
    study: StudyRecord,
    name: str,
    fmt: str,
    cache: FigureCache,
    stage: int | None = None,
    pair: tuple[str, str] | None = None,
    params: tuple[str, ...] | None = None,
    drawer: Any = None,
) -> bytes:
    """Figure ``name`` of ``study`` as SVG or PNG bytes, or as the JSON of its chart
    (``fmt`` "json": what the page draws; :mod:`services.plots.chart`), cached. ``stage``: a
    finished stage (default the last); ``pair``: the parameters of the bivariate density;
    ``drawer``: a :class:`~services.api.dashboard.drawing.FigureProcess` that makes what
    ``cache`` lacks (None: made here). FigureError if the figure does not apply."""
    if name not in STUDY_FIGURES:
        raise FigureError(f"figure: unknown figure {name!r}; one of {sorted(STUDY_FIGURES)}")
    build, needs_stage = STUDY_FIGURES[name]
    kind = KINDS.get(study.kind)
    if kind is None or name not in kind.panel.figures:
        title = study.kind if kind is None else kind.title
        raise FigureError(f"figure {name}: not drawn for a {title} study")
    stages = store.stages.list(study.id)
    if needs_stage:
        done = [s.stage_index for s in stages if s.status == "done"]
        if not done:
            raise FigureError(f"study {study.id} has no finished stage yet")
        if stage is None:
            stage = done[-1]
        elif stage not in done:
            raise FigureError(f"stage {stage} of study {study.id} is not finished")
        key: tuple = (study.id, stage, name, pair, params, fmt)
    else:  # what it shows: the stages' rows and the study's state (not every batch's version)
        rows = tuple((s.stage_index, s.status, s.exponent, s.acceptance, s.ess) for s in stages)
        key = (study.id, study.status, rows, name, fmt)

    def make() -> bytes:
        if drawer is not None:
            options = {"stage": stage, "pair": pair, "params": params}
            return drawer.study_figure(study.id, name, fmt, options)
        made = build(
            store=store,
            study=study,
            stages=stages,
            stage=stage,
            cache=cache,
            pair=pair,
            params=params,
        )
        if fmt == CHART_FORMAT and not isinstance(made, Chart):
            raise FigureError(f"figure {name}: drawn as an image only (svg, png)")
        return _made(made, fmt)

    return cache.get_or_make(key, make)


def _made(made: Chart | Figure, fmt: str) -> bytes:
    """A chart as its JSON (``fmt`` "json") or drawn by matplotlib, or a figure, rendered."""
    if fmt == CHART_FORMAT:
        return json.dumps(made.to_json(), separators=(",", ":"), allow_nan=False).encode()
    fig = plots.mpl.draw(made) if isinstance(made, Chart) else made
    return plots.figures.render(fig, fmt)


def dataset_signals(store: Store, dataset_id: int, fmt: str, cache: FigureCache) -> bytes:
    """A stored log's raw and filtered channels with the averaging window, as an image or
    (``fmt`` "json") its chart's data (cached)."""

    def make() -> bytes:
        return _made(plots.swt.measured_chart(stored_log(store, dataset_id)), fmt)

    return cache.get_or_make(("signals", dataset_id, fmt), make)
