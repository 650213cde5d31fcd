"""From a request to a stored, started study: case, overrides, limits, precheck, creation.

Every check runs before anything is stored; each failure is a :class:`StudyRequestError` whose
message starts with the request's field (``preset``, ``case.parameters.k_phi``, ``n_samples``,
``dataset_ids``, ``bounds.phi`` ...).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import ValidationError

from scm_core.calibration import CaseDefinition, CaseError, StudyModel, preset_case
from scm_core.simulator.layout import pack
from services.config import Settings
from services.limits import (
    INT64_MAX,
    LimitError,
    check_run_size,
    check_simulator_settings,
    check_study_size,
)
from services.store import Store, StudySpec
from worker.morris_study import SensitivityInputError, sensitivity_spec
from worker.orchestrator import StudyInputError, service_batch_size, study_spec


class StudyRequestError(ValueError):
    """A study request that cannot be accepted; the message names the field."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


def base_case(preset: str | None, document: Mapping[str, Any] | None) -> CaseDefinition:
    """The case named by a request: a preset of the paper or a case document (exactly one)."""
    if (preset is None) == (document is None):
        raise StudyRequestError(
            "preset: give exactly one of 'preset' (a name: 1, 2a, 2b) or 'case' (a case document)"
        )
    if preset is not None:
        try:
            return preset_case(preset)
        except CaseError as exc:
            raise StudyRequestError(f"preset: {exc}") from None
    try:
        return CaseDefinition.from_dict(dict(document or {}))
    except CaseError as exc:
        text = str(exc)
        raise StudyRequestError(text if text.startswith("case") else f"case.{text}") from None


def with_overrides(
    case: CaseDefinition, top: Mapping[str, Any], sampler: Mapping[str, Any]
) -> CaseDefinition:
    """``case`` with top-level (name, seed, likelihood) and ``[sampler]`` overrides applied; the
    seed must fit the database (< 2**63)."""
    if sampler or top:
        try:
            case = case.with_changes(**top, **({"sampler": dict(sampler)} if sampler else {}))
        except CaseError as exc:
            raise StudyRequestError(str(exc).removeprefix("sampler.")) from None
    if case.seed > INT64_MAX:
        raise StudyRequestError(f"seed: must be < 2**63 (got {case.seed})")
    return case


def _check_limits(
    settings: Settings, case: CaseDefinition, dataset_ids: list[int], batch_size: int | None
) -> None:
    """The study's size (samples, stages, datasets, batches, model runs) and its simulator
    table against the service's limits, before any dataset is read."""
    sampler = case.tmcmc_settings()
    try:
        check_simulator_settings(settings, dict(case.simulator))
        check_study_size(
            settings,
            n_samples=case.sampler.n_samples,
            max_stages=case.sampler.max_stages,
            steps_per_chain=sampler.n_steps or sampler.max_steps,
            dataset_ids=dataset_ids,
            batch_size=service_batch_size(case, batch_size),
        )
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None


def check_runs(settings: Settings, model: StudyModel, theta: Any, k: int, dataset_id: int) -> None:
    """One run's size (time steps, grid cells, output rate) on dataset ``k`` of ``model`` at
    ``theta`` against the service's limits (the size depends on the wheel, the test
    conditions and the simulator settings, not on the soil)."""
    try:
        prm = pack(*model.configs(theta, k))
    except (ValidationError, ValueError):
        return  # not a valid configuration: the configuration check names the field
    try:
        check_run_size(settings, prm, f"dataset {dataset_id} ({model.datasets[k].name})")
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None


def _precheck(
    store: Store, settings: Settings, case: CaseDefinition, dataset_ids: list[int]
) -> None:
    """Refuse a case whose simulator configuration cannot be built at the prior medians on
    the datasets' test conditions (the study would fail on its first batch), or whose runs
    are over the service's limits."""
    try:
        model = StudyModel(case, [store.datasets.load(d) for d in dataset_ids])
    except (ValidationError, ValueError) as exc:
        raise StudyRequestError(f"dataset_ids: {exc}") from None
    theta = case.prior().ppf(np.full(len(case.parameters), 0.5))
    problem = model.config_problem(theta)
    if problem is not None:
        k, why = problem
        raise StudyRequestError(
            f"dataset_ids: dataset {dataset_ids[k]} ({model.datasets[k].name}): {why}"
        )
    for k in range(model.n_datasets):
        check_runs(settings, model, theta, k, dataset_ids[k])


def calibration_spec(
    store: Store,
    settings: Settings,
    case: CaseDefinition,
    dataset_ids: list[int],
    batch_size: int | None = None,
) -> StudySpec:
    """A TMCMC calibration of ``case`` on stored datasets, checked against the limits and at
    the prior medians; nothing is stored."""
    _check_limits(settings, case, dataset_ids, batch_size)
    try:
        spec = study_spec(store, case, dataset_ids, batch_size)
    except StudyInputError as exc:
        raise StudyRequestError(str(exc)) from None
    _precheck(store, settings, case, list(spec.dataset_ids))
    return spec


def sensitivity_request(
    store: Store, settings: Settings, case: CaseDefinition, dataset_id: int, **design: Any
) -> StudySpec:
    """A Morris screening on one stored dataset (``design``: r, levels, seed, joint_k,
    bounds, batch_size, name), checked against the limits; nothing is stored."""
    try:
        check_simulator_settings(settings, dict(case.simulator))
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None
    try:
        spec = sensitivity_spec(store, case, dataset_id, **design)
    except SensitivityInputError as exc:
        raise StudyRequestError(str(exc)) from None
    try:
        check_study_size(
            settings,
            n_samples=spec.n_samples,
            max_stages=0,
            steps_per_chain=0,
            dataset_ids=spec.dataset_ids,
            batch_size=spec.batch_size,
            samples_field="r",
        )
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None
    model = StudyModel(case, [store.datasets.load(dataset_id)])
    check_runs(settings, model, case.prior().ppf(np.full(len(case.parameters), 0.5)), 0, dataset_id)
    return spec
