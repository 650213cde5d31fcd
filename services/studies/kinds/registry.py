"""The study kinds the service knows, by the name ``studies.kind`` holds. Adding a kind: its
module (see :mod:`.base`) and one line here."""

from __future__ import annotations

from services.store import StudyRecord

from .base import StudyKind, StudyTerms
from .calibration import KIND as CALIBRATION
from .prediction import KIND as PREDICTION
from .sensitivity import KIND as SENSITIVITY
from .update import KIND as UPDATE

__all__ = ["KINDS", "kind_of", "posterior_kinds", "study_terms"]

KINDS: dict[str, StudyKind] = {k.name: k for k in (CALIBRATION, SENSITIVITY, UPDATE, PREDICTION)}


def kind_of(name: str) -> StudyKind:
    """The plug-in of kind ``name``; KeyError naming the known kinds if there is none."""
    try:
        return KINDS[name]
    except KeyError:
        raise KeyError(f"unknown study kind {name!r}; one of {sorted(KINDS)}") from None


def study_terms(study: StudyRecord) -> StudyTerms:
    """Priors, sampler and simulator settings of a stored study, derived by its kind from its
    case and payload (empty documents for a kind this service does not know)."""
    kind = KINDS.get(study.kind)
    return StudyTerms({}, {}, {}) if kind is None else kind.terms(study)


def posterior_kinds() -> list[str]:
    """The kinds whose stages temper to a posterior (``StudyKind.posterior``)."""
    return [name for name, kind in KINDS.items() if kind.posterior]
