"""Checks every kind makes of a simulator configuration before a study is stored."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from scm_core.calibration import CaseDefinition, StudyModel
from scm_core.simulator.layout import pack
from services.config import Settings
from services.limits import LimitError, check_run_size

from ..errors import StudyRequestError

__all__ = ["check_runs", "prior_medians"]


def prior_medians(case: CaseDefinition) -> NDArray[np.float64]:
    """The case's parameters at their prior medians (where configurations are checked)."""
    return case.prior().ppf(np.full(len(case.parameters), 0.5))


def check_runs(settings: Settings, model: StudyModel, theta: Any, k: int, where: int | str) -> None:
    """One run's size (time steps, grid cells, output rate) on dataset ``k`` of ``model`` at
    ``theta`` against the service's limits (the size depends on the wheel, the test
    conditions and the simulator settings, not on the soil). ``where``: the stored dataset's
    id, or the request field the conditions came from."""
    try:
        prm = pack(*model.configs(theta, k))
    except (ValidationError, ValueError):
        return  # not a valid configuration: the configuration check names the field
    try:
        label = where if isinstance(where, str) else f"dataset {where}"
        check_run_size(settings, prm, f"{label} ({model.datasets[k].name})")
    except LimitError as exc:
        raise StudyRequestError(str(exc)) from None
