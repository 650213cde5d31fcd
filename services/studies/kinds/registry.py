"""The study kinds the service knows, by the name ``studies.kind`` holds. Adding a kind: its
module (see :mod:`.base`) and one line here."""

from __future__ import annotations

from .base import StudyKind
from .calibration import KIND as CALIBRATION
from .prediction import KIND as PREDICTION
from .screening import KIND as SCREENING
from .update import KIND as UPDATE

__all__ = ["KINDS", "kind_of"]

KINDS: dict[str, StudyKind] = {k.name: k for k in (CALIBRATION, SCREENING, UPDATE, PREDICTION)}


def kind_of(name: str) -> StudyKind:
    """The plug-in of kind ``name``; KeyError naming the known kinds if there is none."""
    try:
        return KINDS[name]
    except KeyError:
        raise KeyError(f"unknown study kind {name!r}; one of {sorted(KINDS)}") from None
