"""Kind "update": a posterior update with new tests (paper section 5.3).

Stage 0 is the final population of an earlier completed calibration (or update), the parent;
the stages temper the new datasets' likelihood only, with the old datasets' likelihood in the
base density (:class:`scm_core.calibration.UpdateLikelihood`), so the result targets
prior x L(old) x L(new). The case (so the priors and sampler settings) is the parent's. The study's
log evidence is the incremental one, log Z(new | old); the total, log Z(old) + log Z(new | old),
is in its ``result`` with the parent's. Payload: ``{"update_of": parent id}``; ``dataset_ids``
are the new datasets only (the old ones are the parent's, recursively). Seed: the request's,
else the parent's + 1, so its chains never reuse the parent's random numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from scm_core.calibration import CaseError, StudyModel, UpdateLikelihood
from scm_core.inference.tmcmc.loop import PopulationStart
from scm_core.inference.tmcmc.stage import StageState
from scm_core.seeds import SEED_MAX
from services.config import Settings
from services.limits import seed_error
from services.stages import DatabaseStages
from services.store import NotFoundError, Store, StudyRecord, StudySpec

from ..batching import DEFAULT_BATCH_SIZE, batch_size_of
from ..datasets import check_dataset_ids, load_datasets
from ..errors import StudyRequestError
from .base import KindPanel, stored_case
from .calibration import (
    POSTERIOR_FIGURES,
    CalibrationKind,
    CalibrationRun,
    check_limits,
    precheck,
)
from .calibration_request import SAMPLER_OVERRIDES

__all__ = [
    "KIND",
    "UpdateRun",
    "completed_calibration",
    "old_dataset_ids",
    "update_request",
    "update_seed",
    "update_spec",
]

#: kinds whose final population an update can start from (a calibration's, an update's)
UPDATABLE = (CalibrationKind.name, "update")


def old_dataset_ids(store: Store, parent: StudyRecord) -> list[int]:
    """The datasets behind ``parent``'s posterior, in likelihood order (its ancestors' first)."""
    chain: list[StudyRecord] = [parent]
    while chain[-1].kind == "update":
        chain.append(store.studies.get(int((chain[-1].payload or {})["update_of"])))
    return [int(d) for study in reversed(chain) for d in study.dataset_ids]


def completed_calibration(store: Store, study_id: int, field: str, what: str) -> StudyRecord:
    """The completed calibration (or update) ``study_id`` whose posterior a new study starts
    from; StudyRequestError naming ``field`` otherwise (``what`` ends the message: "only a
    completed calibration <what>")."""
    try:
        study = store.studies.get(int(study_id))
    except NotFoundError:
        raise StudyRequestError(f"{field}: no study with id {study_id}") from None
    if study.kind not in UPDATABLE:
        raise StudyRequestError(
            f"{field}: study {study.id} is a {study.kind} study, not a calibration"
        )
    if study.status != "completed":
        raise StudyRequestError(
            f"{field}: study {study.id} is {study.status}; only a completed calibration {what}"
        )
    return study


def update_seed(parent_seed: int) -> int:
    """The seed of an update of a study seeded ``parent_seed`` when none is given: the next
    one (wrapping to 0 after the largest, 2**63 - 1), so that the update's random numbers are
    not the parent's (the CLI's ``--update-of`` uses the same, for the same samples)."""
    return (int(parent_seed) + 1) % (SEED_MAX + 1)


def update_spec(
    store: Store,
    settings: Settings,
    update_of: int,
    dataset_ids: Sequence[int],
    *,
    seed: int | None = None,
    batch_size: int | None = None,
    name: str | None = None,
    max_stages: int | None = None,
) -> StudySpec:
    """An update of the completed study ``update_of`` with the stored ``dataset_ids``, checked
    like a calibration (limits, configuration at the prior medians); nothing is stored.
    The case is the parent's, with ``max_stages`` if given (when to stop does not change the
    samples). StudyRequestError names the field (``update_of``, ``dataset_ids``, ``seed``,
    ``max_stages``)."""
    parent = completed_calibration(store, update_of, "update_of", "can be updated")
    ids = [int(d) for d in dataset_ids]
    check_dataset_ids(store, ids)
    old = old_dataset_ids(store, parent)
    again = [d for d in ids if d in old]
    if again:
        raise StudyRequestError(
            f"dataset_ids: dataset {again[0]} is already in the posterior of study {parent.id}"
        )
    case = stored_case(parent.case)
    document = parent.case
    if max_stages is not None and max_stages != case.sampler.max_stages:
        try:
            case = case.with_changes(sampler={"max_stages": int(max_stages)})
        except CaseError as exc:
            raise StudyRequestError(str(exc).removeprefix("sampler.")) from None
        document = case.to_dict()
    if seed is None:
        seed = update_seed(parent.seed)
    if why := seed_error(seed):
        raise StudyRequestError(f"seed: {why}")
    size = batch_size_of(batch_size, parent.batch_size, DEFAULT_BATCH_SIZE)
    check_limits(settings, case, old + ids, size)
    precheck(store, settings, case, ids)
    return StudySpec(
        name=name or f"{parent.name} + update",
        case=document,
        dataset_ids=ids,
        seed=int(seed),
        n_samples=parent.n_samples,
        batch_size=size,
        kind=KIND.name,
        payload={"update_of": parent.id},
        parent_id=parent.id,
    )


def update_request(store: Store, settings: Settings, body: Any) -> StudySpec:
    """The spec of the posterior update a calibration's request (``POST /studies`` with
    ``update_of``) asks for; the case's fields cannot be given with it."""
    if body.runs > 1:
        raise StudyRequestError("runs: an update (update_of) is one study; give runs 1")
    fixed = ("preset", "case", "likelihood", *SAMPLER_OVERRIDES)
    given = [k for k in fixed if getattr(body, k) is not None]
    if given:
        raise StudyRequestError(
            f"{given[0]}: an update keeps the case of study {body.update_of}; give only "
            "update_of, dataset_ids, seed, name and batch_size"
        )
    return update_spec(
        store,
        settings,
        body.update_of or 0,
        body.dataset_ids,
        seed=body.seed,
        batch_size=body.batch_size,
        name=body.name,
    )


@dataclass
class UpdateRun(CalibrationRun):
    """A calibration run whose stage 0 is the parent's population and whose likelihood puts
    the old datasets in the base density."""

    likelihood: UpdateLikelihood | None = None
    parent_final: StageState | None = None
    parent_id: int = 0
    parent_log_evidence: float = 0.0

    @property
    def start(self) -> PopulationStart:
        """The parent's final population (see ``UpdateLikelihood.start``)."""
        return self.likelihood.start(self.parent_final)

    @property
    def model_function(self):
        """Points (m, d) -> (log L(new), responses, log L(old))."""
        return self.likelihood

    def result(self, final: StageState) -> dict[str, Any]:
        increment = float(final.log_evidence)
        return {
            "update_of": self.parent_id,
            "log_evidence_increment": increment,
            "parent_log_evidence": self.parent_log_evidence,
            "log_evidence_total": self.parent_log_evidence + increment,
        }


class UpdateKind(CalibrationKind):
    """The plug-in of kind "update" (see :mod:`.base`); batches and reducer as a calibration."""

    name = "update"
    title = "posterior update"
    http = None  # POST /studies with update_of
    cli = None  # scm-calib calibrate --update-of
    collection = "/studies"
    posterior = True
    panel = KindPanel(
        template="kinds/posterior.html",
        figures=POSTERIOR_FIGURES,
        start="earlier posterior",
        end="updated posterior",
        stage_zero="the earlier posterior: not yet updated",
        stage_zero_heading="Earlier posterior (stage 0: the study this one updates)",
    )

    def build(self, store: Store, study: StudyRecord) -> UpdateRun:
        parent = store.studies.get(int((study.payload or {})["update_of"]))
        old = old_dataset_ids(store, parent)
        case = stored_case(study.case)
        model = StudyModel(case, load_datasets(store, case, old + list(study.dataset_ids)))
        final = DatabaseStages(store, parent.id).state(-1)  # a completed study's posterior
        return UpdateRun(
            case=case,
            model=model,
            settings=case.tmcmc_settings(),
            n_samples=study.n_samples,
            seed=study.seed,
            likelihood=UpdateLikelihood(model, len(old)),
            parent_final=final,
            parent_id=parent.id,
            parent_log_evidence=_total_log_evidence(store, parent),
        )


def _total_log_evidence(store: Store, study: StudyRecord) -> float:
    """log Z of all the data behind ``study``'s posterior: the total its result holds (an
    update's, or that of an update's stages adopted from a results folder), else its log
    evidence."""
    if study.result and "log_evidence_total" in study.result:
        return float(study.result["log_evidence_total"])
    return float(study.log_evidence if study.log_evidence is not None else np.nan)


KIND = UpdateKind()
