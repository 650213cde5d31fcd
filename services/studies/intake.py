"""From a request to a case: a preset or a case document, with overrides.

Every check runs before anything is stored; each failure is a :class:`StudyRequestError` whose
message starts with the request's field (``preset``, ``case.parameters.k_phi``, ``seed`` ...).
The kinds (:mod:`.kinds`) check the rest of a request (datasets, limits, configuration).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

from scm_core.calibration import CaseDefinition, CaseError, preset_case
from services.limits import run_seeds, seed_error
from services.store import StudySpec

from .errors import StudyRequestError

__all__ = ["base_case", "group_name", "run_name", "run_specs", "with_overrides"]

_RUN_SUFFIX = re.compile(r" \(run [0-9]+/[0-9]+\)$")


def run_name(name: str, k: int, runs: int) -> str:
    """The name of run ``k`` (from 1) of ``runs`` of the study ``name``."""
    return f"{name} (run {k}/{runs})"[:200]


def group_name(name: str) -> str:
    """The study's name without its run's suffix (:func:`run_name`)."""
    return _RUN_SUFFIX.sub("", name)


def base_case(preset: str | None, document: Mapping[str, Any] | None) -> CaseDefinition:
    """The case named by a request: a preset of the paper or a case document (exactly one)."""
    if (preset is None) == (document is None):
        raise StudyRequestError(
            "preset: give exactly one of 'preset' (a name: quick, 1, 2a, 2b) or 'case' (a case "
            "document)"
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


def case_from_toml(text: str) -> CaseDefinition:
    """The case of a TOML case file's text, checked as the command line checks it;
    StudyRequestError("toml: <the command line's message>")."""
    try:
        return CaseDefinition.from_toml(text)
    except CaseError as exc:
        raise StudyRequestError(f"toml: {' '.join(str(exc).split())}") from None


def with_overrides(
    case: CaseDefinition, top: Mapping[str, Any], sampler: Mapping[str, Any]
) -> CaseDefinition:
    """``case`` with top-level (name, seed, likelihood) and ``[sampler]`` overrides applied; the
    seed must fit the database (:func:`services.limits.seed_error`)."""
    if sampler or top:
        try:
            case = case.with_changes(**top, **({"sampler": dict(sampler)} if sampler else {}))
        except CaseError as exc:
            raise StudyRequestError(str(exc).removeprefix("sampler.")) from None
    if why := seed_error(case.seed):
        raise StudyRequestError(f"seed: {why}")
    return case


def run_specs(case: CaseDefinition, spec: StudySpec, runs: int) -> list[StudySpec]:
    """The studies of ``runs`` repeated runs of the checked ``spec`` of ``case``: the seeds
    seed, seed + 1, ..., named "(run k/K)" (the checks do not depend on seed or name, so they
    are not repeated)."""
    if runs == 1:
        return [spec]
    try:
        seeds = run_seeds(case.seed, runs)
    except ValueError as exc:
        raise StudyRequestError(f"runs: {exc}") from None
    out = []
    for k, seed in enumerate(seeds):
        run = case.with_changes(seed=seed, name=run_name(case.name, k + 1, runs))
        out.append(replace(spec, name=run.name, case=run.to_dict(), seed=run.seed))
    return out
