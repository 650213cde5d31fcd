"""One repository per aggregate; every public method is one transaction."""

from .base import Database
from .batches import BatchRepository
from .datasets import DatasetRepository
from .events import EventRepository
from .samples import SampleRepository
from .stages import StageRepository
from .studies import StudyRepository

__all__ = [
    "BatchRepository",
    "Database",
    "DatasetRepository",
    "EventRepository",
    "SampleRepository",
    "StageRepository",
    "StudyRepository",
]
