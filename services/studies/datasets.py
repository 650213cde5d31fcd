"""A study's datasets as the simulator's likelihood reads them."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from scm_core.calibration import CaseDefinition
from scm_core.signals import SWTDataset, load_log, load_summary
from scm_core.signals.processing import default_cutoff
from services.store import NotFoundError, Store

from .errors import StudyRequestError

__all__ = ["check_dataset_ids", "load_datasets", "stored_log"]

#: averaging offset (s) of a log whose stored processing names none
DEFAULT_OFFSET = 40.0


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
    """SWT datasets of a study, processed with the case's data settings (offset, cutoff).

    The processing stored at upload is reused when it is the one the case asks for (a summary
    always; a log when its averaging offset and low-pass cutoff are the case's): the steady
    means and standard errors are then those of processing the raw bytes again, bit for bit
    (tested), without reading or filtering them in every worker. Otherwise the raw log is
    processed with the case's settings."""
    out: list[SWTDataset] = []
    for did in dataset_ids:
        rec = store.datasets.get(did)
        stored = store.datasets.load(did)
        if _processed_as_case_asks(stored, case):
            out.append(replace(stored, name=rec.name, series=None))
        elif rec.source_kind == "timeseries":
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


def _processed_as_case_asks(stored: SWTDataset, case: CaseDefinition) -> bool:
    if stored.source_kind != "timeseries":
        return True  # a summary's means do not depend on the case
    if stored.offset is None or stored.rate_hz is None or stored.cutoff_hz is None:
        return False
    cutoff = (
        case.data.cutoff_hz if case.data.cutoff_hz is not None else default_cutoff(stored.rate_hz)
    )
    return stored.offset == case.data.offset and stored.cutoff_hz == cutoff


def stored_log(store: Store, dataset_id: int) -> SWTDataset:
    """A stored log with its series (raw and filtered channels), processed as at upload
    (its stored offset and cutoff). NotFoundError for an unknown dataset; ValueError for a
    summary dataset or a log stored without its raw bytes."""
    rec = store.datasets.get(dataset_id)
    if rec.source_kind != "timeseries":
        raise ValueError(f"dataset {dataset_id} is a summary dataset: it has no series")
    raw = store.datasets.raw(dataset_id)
    if raw is None:
        raise ValueError(f"dataset {dataset_id} was stored without its raw log")
    p = rec.processed
    cutoff = p.get("cutoff_hz")
    return load_log(
        raw,
        metadata=rec.meta or None,
        offset=float(p.get("offset") or DEFAULT_OFFSET),
        cutoff_hz=None if cutoff is None else float(cutoff),
        name=rec.name,
    )
