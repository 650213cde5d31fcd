"""A study's datasets as the simulator's likelihood reads them."""

from __future__ import annotations

from collections.abc import Sequence

from scm_core.calibration import CaseDefinition
from scm_core.signals import SWTDataset, load_log, load_summary
from services.store import NotFoundError, Store

from .errors import StudyRequestError

__all__ = ["check_dataset_ids", "load_datasets"]


def check_dataset_ids(store: Store, dataset_ids: Sequence[int], field: str = "dataset_ids") -> None:
    """At least one dataset, none listed twice, all stored; else StudyRequestError(``field``)."""
    if not dataset_ids:
        raise StudyRequestError(f"{field}: at least one dataset is needed")
    if len(set(dataset_ids)) != len(dataset_ids):
        raise StudyRequestError(f"{field}: a dataset is listed twice")
    for did in dataset_ids:
        try:
            store.datasets.get(int(did))
        except NotFoundError:
            raise StudyRequestError(f"{field}: no dataset with id {did}") from None


def load_datasets(
    store: Store, case: CaseDefinition, dataset_ids: Sequence[int]
) -> list[SWTDataset]:
    """SWT datasets of a study, processed with the case's data settings (offset, cutoff)."""
    out: list[SWTDataset] = []
    for did in dataset_ids:
        rec = store.datasets.get(did)
        if rec.source_kind == "timeseries":
            out.append(
                load_log(
                    store.datasets.raw(did),
                    metadata=rec.meta or None,
                    offset=case.data.offset,
                    cutoff_hz=case.data.cutoff_hz,
                    name=rec.name,
                    keep_series=False,
                )
            )
        else:
            out.append(load_summary(store.datasets.raw(did), metadata=rec.meta or None))
    return out
