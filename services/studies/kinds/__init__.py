"""Study kinds as plug-ins: one module per kind (:mod:`.calibration`, :mod:`.screening`), the
protocol they follow (:mod:`.base`) and the registry (:mod:`.registry`)."""

from .base import StudyKind, StudyRun
from .registry import KINDS, kind_of

__all__ = ["KINDS", "StudyKind", "StudyRun", "kind_of"]
