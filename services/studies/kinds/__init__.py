"""Study kinds as plug-ins: one module per kind (:mod:`.calibration`, :mod:`.sensitivity`,
:mod:`.update`, :mod:`.prediction`; the calibration's request model in
:mod:`.calibration_request`), the protocol they follow (:mod:`.base`) and the registry
(:mod:`.registry`)."""

from .base import KindPanel, StudyKind, StudyRun, StudyTerms
from .registry import KINDS, kind_of, posterior_kinds, study_terms

__all__ = [
    "KINDS",
    "KindPanel",
    "StudyKind",
    "StudyRun",
    "StudyTerms",
    "kind_of",
    "posterior_kinds",
    "study_terms",
]
