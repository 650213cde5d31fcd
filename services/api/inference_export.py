"""A stored calibration as an ArviZ InferenceData file (``GET /studies/{id}/inference-data``):
the same groups as ``scm-calib export --to netcdf`` (:mod:`services.exports.inference_data`),
built from the store instead of a results folder."""

from __future__ import annotations

import tempfile
import threading
import warnings
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from fastapi import HTTPException

from scm_core.jsondoc import finite_or_none
from services.stages import DatabaseStages, StageStoreError, run_population
from services.store import Store
from services.studies.kinds.update import UPDATABLE

from .views import agreement_of, parameter_names, parameter_units


class NetcdfCache:
    """The last ``size`` files made, by (study ids, their versions): a study's file changes
    only with the study (every stage and event raises its version), and making one costs
    ~0.2 s."""

    def __init__(self, size: int = 8) -> None:
        self._items: OrderedDict[tuple, bytes] = OrderedDict()
        self._lock = threading.Lock()
        self._size = size

    def get(self, store: Store, study_ids: Sequence[int], versions: Sequence[int]) -> bytes:
        key = (tuple(study_ids), tuple(versions))
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        data = studies_netcdf(store, study_ids)
        with self._lock:
            self._items[key] = data
            while len(self._items) > self._size:
                self._items.popitem(last=False)
        return data


def _run(store: Store, study_id: int):
    """(study, its RunPopulation); 409 as :func:`studies_netcdf`."""
    study = store.studies.get(study_id)
    if study.kind not in UPDATABLE:
        raise HTTPException(409, f"study {study_id} is a {study.kind} study, not a calibration")
    try:
        run = run_population(DatabaseStages(store, study_id))
    except StageStoreError as exc:
        raise HTTPException(409, f"study {study_id}: {exc}") from None
    return study, run


def studies_netcdf(store: Store, study_ids: Sequence[int]) -> bytes:
    """The NetCDF bytes of studies (one, or the runs of a run group: one chain each): each
    one's last finished stage (with its stage 0 as the prior); 409 for a study that is not a
    calibration or has no finished stage after stage 0, or runs of different sizes. Several
    runs carry their agreement (R-hat, verdict) in the attributes."""
    from services.exports.inference_data import inference_data

    loaded = [_run(store, sid) for sid in study_ids]
    study, _ = loaded[0]
    lasts = [run.stages[-1] for _, run in loaded]  # each run's last finished stage
    last = lasts[0]
    names = parameter_names(study)
    if any(parameter_names(s) != names for s, _ in loaded):
        raise HTTPException(409, f"studies {list(study_ids)} calibrate different parameters")
    observed = {}
    for dataset_id in study.dataset_ids:
        d = store.datasets.get(dataset_id)
        observed[d.name] = {"means": d.means, "standard_errors": d.standard_errors}
    exponent = finite_or_none(last.exponent)
    attrs: dict = {
        "study_id": study.id,
        "case": study.case,
        "status": study.status,
        "is_posterior": exponent is not None and exponent >= 1.0 - 1e-12,
        "log_evidence": finite_or_none(last.log_evidence),
        "seed": study.seed,
    }
    runs = [run for _, run in loaded]
    with warnings.catch_warnings():  # ArviZ announces its refactor on import
        warnings.simplefilter("ignore", FutureWarning)
        if len(loaded) > 1:
            sizes = {r.samples.shape[0] for r in runs}
            if len(sizes) > 1:
                raise HTTPException(409, f"the runs differ in size {sorted(sizes)}")
            chains = np.stack([r.samples for r in runs])
            agreement = agreement_of(chains, names, [s for s, _ in loaded])
            attrs.update(
                study_id=[s.id for s, _ in loaded],
                seed=[s.seed for s, _ in loaded],
                status=[s.status for s, _ in loaded],
                is_posterior=all(
                    (finite_or_none(st.exponent) or 0.0) >= 1.0 - 1e-12 for st in lasts
                ),
                log_evidence=[finite_or_none(st.log_evidence) for st in lasts],
                verdict=None if agreement is None else agreement.verdict,
                converged=None if agreement is None else agreement.converged,
            )
        idata = inference_data(
            names, runs, units=parameter_units(study), observed=observed, attrs=attrs
        )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "inference_data.nc"
        idata.to_netcdf(str(path))
        return path.read_bytes()
