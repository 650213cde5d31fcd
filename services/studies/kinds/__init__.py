"""Study kinds as plug-ins: one module per kind (:mod:`.calibration`, :mod:`.screening`,
:mod:`.update`, :mod:`.prediction`), the protocol they follow (:mod:`.base`) and the registry
(:mod:`.registry`)."""

from .base import StudyKind, StudyRun, StudyTerms
from .registry import KINDS, kind_of, study_terms

__all__ = ["KINDS", "StudyKind", "StudyRun", "StudyTerms", "kind_of", "study_terms"]
