"""What a study kind provides (the plug-in protocol) and the helpers kinds share.

A kind turns a request into a :class:`~services.store.StudySpec` (validation, in its module),
builds the computation of a stored study (:meth:`StudyKind.build`), computes a work batch
(:meth:`StudyRun.compute`, pure: same lease, same bytes), reduces a finished stage
(:meth:`StudyRun.reducer`) and says how many model runs each batch of a stage plans
(:meth:`StudyKind.planned_runs`, for progress) and derives what a stored study is from its
case document and payload (:meth:`StudyKind.terms`: the case is the single source). The
store sees only blobs and
:class:`~services.store.ReducedStage` records; the worker sees only this protocol.

A kind says how the dashboard shows it (:class:`KindPanel`: its part of a study page, the
figures drawn for it, its words for what its stages hold), so the dashboard spells no kind's
name. A kind brings its part of the HTTP API (:class:`KindHttp`: a path, a request model, its
validation into one study or several and the model of its result); the API mounts
``POST PATH``, ``GET PATH`` and ``GET PATH/{id}`` (or only ``POST PATH``, a create route
answering the common study) for every kind of the registry that has one, so a new kind needs
its module and a line in the registry, nothing in the API. A kind may bring
a command of the ``scm-calib`` command line (:class:`KindCli`), which the CLI mounts from the
registry likewise.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel

from scm_core.calibration import CaseDefinition
from services.config import Settings
from services.store import BatchLease, BatchOutput, Reducer, Store, StudyRecord, StudySpec
from services.store.codec import encode

__all__ = [
    "KindCli",
    "KindHttp",
    "KindPanel",
    "ModelFunction",
    "StudyKind",
    "StudyRun",
    "StudyTerms",
    "batch_output",
    "case_terms",
    "stored_case",
]

#: points (m, d) -> what the kind's batches need per point (log-likelihoods, responses ...)
ModelFunction = Callable[[NDArray[np.float64]], Any]


class StudyRun(Protocol):
    """The computation of one study, built once per process and cached."""

    @property
    def model_function(self) -> ModelFunction:
        """The function whose time is simulator time (the worker times it)."""
        ...

    def compute(self, store: Store, lease: BatchLease, model_function: Any) -> BatchOutput:
        """The result of the leased batch (the same bytes however often it runs)."""
        ...

    def reducer(self, workers: int) -> Reducer:
        """The reducer of the study's stages (next stages cut for ``workers`` workers)."""
        ...


@dataclass(frozen=True)
class KindHttp:
    """A kind's part of the HTTP API (mounted by ``services.api`` for every kind that has one,
    the same way for all).

    ``path``: the collection ("/predictions"); ``request``: the body of ``POST path`` (a
    pydantic model; unknown fields should be refused); ``spec(store, settings, body)``: the
    validated study, or several (repeated runs, stored as one run group; the answer is the
    first), StudyRequestError naming the field, nothing stored; ``result``: the model of the
    study's stored ``result`` (None: any JSON object); ``description``: the POST's
    documentation (``summary``: its title; default "Submit a <title>"). ``fields``: the
    kind's own top-level fields of a study it shows (a pydantic model, e.g. a screening's
    design), made by ``fields_of(study)`` from the stored study; None: the study, its
    payload, progress and result only. ``reads``: ``GET path`` and ``GET path/{id}`` are
    mounted too; False: the kind brings only its create route, which answers the common
    study (``GET /studies/{id}``: its studies are read as every study is). ``statuses``: the
    error statuses the POST documents."""

    path: str
    request: type[BaseModel]
    spec: Callable[[Store, Settings, Any], StudySpec | Sequence[StudySpec]]
    result: type[BaseModel] | None
    description: str
    fields: type[BaseModel] | None = None
    fields_of: Callable[[StudyRecord], BaseModel] | None = None
    reads: bool = True
    summary: str | None = None
    statuses: tuple[int, ...] = (401, 404, 413, 422)


@dataclass(frozen=True)
class KindCli:
    """A kind's command of the ``scm-calib`` command line (mounted by ``services.cli``):
    ``name`` (``scm-calib NAME``) and ``command``, the click command as ``"module:attribute"``,
    imported only when the command runs (the command line starts without the kinds' heavy
    imports)."""

    name: str
    command: str


@dataclass(frozen=True)
class KindPanel:
    """How the dashboard shows a study of the kind (``services.api.dashboard``).

    ``template``: the kind's part of a study page's results, a Jinja template by its name in
    the dashboard's templates or in ``templates`` (a directory of the kind's own); it sees
    ``study``, ``kind``, ``stage``, ``result`` and the page's other context. ``figures``: the
    study figures drawn for it (names of ``services.api.dashboard.study_figures.STUDY_FIGURES``).
    ``counts``: what the study's ``n_samples`` counts. For a kind with a posterior, ``start``
    and ``end`` name stage 0's sample and the last stage's in labels ("prior", "posterior"),
    ``stage_zero`` says what stage 0 is where a figure shows it, ``stage_zero_heading`` heads
    its summary."""

    template: str
    figures: tuple[str, ...] = ()
    counts: str = "samples per stage"
    start: str = "prior"
    end: str = "posterior"
    stage_zero: str = "the prior sample: not a posterior"
    stage_zero_heading: str = "Prior sample (stage 0: no tempering stage has finished)"
    templates: Path | None = None


@dataclass(frozen=True)
class StudyTerms:
    """What a stored study is, derived from its case document and payload when read.

    ``priors``: the columns of its samples as a prior document (``JointPrior.to_dict()``
    form; a screening's factor box); ``sampler``: its sampler or design settings;
    ``simulator``: the case's simulator settings."""

    priors: dict[str, Any]
    sampler: dict[str, Any]
    simulator: dict[str, Any]

    @property
    def parameter_names(self) -> list[str]:
        return [str(p["name"]) for p in self.priors.get("parameters", [])]

    @property
    def parameter_units(self) -> dict[str, str | None]:
        return {str(p["name"]): p.get("unit") for p in self.priors.get("parameters", [])}


@lru_cache(maxsize=256)
def _stored_case(text: str) -> CaseDefinition:
    return CaseDefinition.from_stored(json.loads(text))


def stored_case(case: Mapping[str, Any]) -> CaseDefinition:
    """The validated case of a stored study's case document, parsed once per process and
    distinct document (the case is immutable: callers share it)."""
    return _stored_case(json.dumps(case, allow_nan=True))


@lru_cache(maxsize=256)
def _case_terms(text: str) -> StudyTerms:
    case = _stored_case(text)
    return StudyTerms(case.prior().to_dict(), case.tmcmc_settings().to_dict(), dict(case.simulator))


def case_terms(case: Mapping[str, Any]) -> StudyTerms:
    """The priors, TMCMC settings and simulator settings of a case document (cached: a page
    of studies derives them once per distinct case). Treat the result as read-only."""
    return _case_terms(json.dumps(case, allow_nan=True))


class StudyKind(Protocol):
    """A kind of study; ``name`` is what ``studies.kind`` holds; ``title`` what one study of
    the kind is called on pages ("posterior update"); ``http`` its part of the API (None:
    studies of the kind are made by another kind's route, e.g. an update by a calibration's
    ``POST /studies`` with ``update_of``);
    ``collection``: the API path its studies are read under, with their results
    (``GET COLLECTION/{id}``); ``posterior``: its stages temper to a posterior (a summary, log
    evidence, comparisons and pooling apply); ``panel``: how the dashboard shows it; ``cli``:
    its command line command, if it has one of its own."""

    name: str
    title: str
    http: KindHttp | None
    cli: KindCli | None
    collection: str
    posterior: bool
    panel: KindPanel

    def build(self, store: Store, study: StudyRecord) -> StudyRun:
        """The computation of ``study`` (its datasets read from the store)."""
        ...

    def planned_runs(self, plan: bytes | None, batches: Sequence[range]) -> list[int]:
        """Model runs each batch of a stage will make (``plan``: the stage's plan blob)."""
        ...

    def terms(self, study: StudyRecord) -> StudyTerms:
        """Priors, sampler and simulator settings of ``study``, from its case and payload."""
        ...


def batch_output(lease: BatchLease, result: Any, model_runs: int | None = None) -> BatchOutput:
    """A kind's batch result (a serialisable dataclass) as the store keeps it; ``model_runs``:
    the runs it holds, where they may differ from the planned ones."""
    k = lease.key
    return BatchOutput(
        k.stage_index, lease.chain_start, lease.chain_stop, encode(result), model_runs
    )


def one_run_per_item(batches: Sequence[range]) -> list[int]:
    """Planned runs of batches whose items (points) cost one model run each."""
    return [len(r) for r in batches]
