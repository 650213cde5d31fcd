"""A stored calibration as an ArviZ InferenceData file (``GET /studies/{id}/inference-data``):
the same groups as ``scm-calib export --to netcdf`` (:mod:`services.exports.inference_data`),
built from the store instead of a results folder."""

from __future__ import annotations

import tempfile
import threading
import warnings
from collections import OrderedDict
from pathlib import Path

from fastapi import HTTPException

from scm_core.jsondoc import finite_or_none
from services.store import Store
from services.studies.kinds.update import UPDATABLE

from .views import parameter_names, parameter_units, resolve_stage


class NetcdfCache:
    """The last ``size`` files made, by (study id, study version): a study's file changes only
    with the study (every stage and event raises its version), and making one costs ~0.2 s."""

    def __init__(self, size: int = 8) -> None:
        self._items: OrderedDict[tuple[int, int], bytes] = OrderedDict()
        self._lock = threading.Lock()
        self._size = size

    def get(self, store: Store, study_id: int, version: int) -> bytes:
        key = (study_id, version)
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        data = study_netcdf(store, study_id)
        with self._lock:
            self._items[key] = data
            while len(self._items) > self._size:
                self._items.popitem(last=False)
        return data


def study_netcdf(store: Store, study_id: int) -> bytes:
    """The NetCDF bytes of study ``study_id``'s last finished stage (with its stage 0 as the
    prior); 409 for a study that is not a calibration or has no finished stage after stage 0."""
    from services.exports.inference_data import RunPopulation, StageRow, inference_data

    study = store.studies.get(study_id)
    if study.kind not in UPDATABLE:
        raise HTTPException(409, f"study {study_id} is a {study.kind} study, not a calibration")
    last = resolve_stage(store, study_id, -1)
    if last.stage_index == 0:
        raise HTTPException(409, f"study {study_id}: no tempering stage has finished yet")
    names = parameter_names(study)
    final = store.samples.arrays(study_id, last.stage_index)
    prior = store.samples.arrays(study_id, 0)
    stages = [
        StageRow.of(s.exponent, s.acceptance, s.log_evidence)
        for s in store.stages.list(study_id)
        if s.status == "done"
    ]
    run = RunPopulation(final.samples, final.log_likelihood, final.log_prior, prior.samples, stages)
    observed = {}
    for dataset_id in study.dataset_ids:
        d = store.datasets.get(dataset_id)
        observed[d.name] = {"means": d.means, "standard_errors": d.standard_errors}
    exponent = finite_or_none(last.exponent)
    attrs = {
        "study_id": study_id,
        "case": study.case,
        "status": study.status,
        "is_posterior": exponent is not None and exponent >= 1.0 - 1e-12,
        "log_evidence": finite_or_none(last.log_evidence),
        "seed": study.seed,
    }
    with warnings.catch_warnings():  # ArviZ announces its refactor on import
        warnings.simplefilter("ignore", FutureWarning)
        idata = inference_data(
            names, [run], units=parameter_units(study), observed=observed, attrs=attrs
        )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "inference_data.nc"
        idata.to_netcdf(str(path))
        return path.read_bytes()
