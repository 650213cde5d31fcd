"""A calibration as an ArviZ ``InferenceData`` (NetCDF): the posterior where ArviZ users look.

Groups (ArviZ's schema; ``chain`` is a run: one study is one chain, repeated runs of a case are
several):

* ``posterior``: the final population of each run, one variable per calibrated parameter
  (dims chain, draw; units in the variable's ``units`` attribute). A TMCMC population after its
  last resampling is an equally weighted sample, so ArviZ's summaries apply as they are.
* ``prior``: stage 0 (the prior draws; for an update, the earlier posterior it started from).
* ``sample_stats``: ``log_likelihood``, ``log_prior`` and ``lp`` (their sum, ArviZ's name for
  the log posterior density) of each draw.
* ``tempering`` (a group of this tool's own): per run and stage (dims chain, stage) the
  tempering ``exponent``, the ``acceptance_rate`` and the ``log_evidence`` so far.
* ``observed_data``: the datasets' steady means of F [N], T [N m] and z [m], and of the
  lateral force Fy [N] where a dataset measured it (dim ``dataset``; NaN where a dataset lacks
  the response), and their standard errors (``F_se``, ...).
* ``posterior_predictive`` (when ``scm-calib predict`` was run on the study's datasets): F, T,
  z (and Fy, where predicted) of each predicted posterior draw under each dataset's conditions,
  with the prediction noise (dims chain, draw, dataset; NaN for a failed run or a dataset not
  predicted), so that ``az.plot_ppc`` sets them against ``observed_data``.

Attributes: the case (JSON), the run status, whether it is a posterior (the tempering reached
exponent 1), the log evidence and the versions of scm-calib, numpy and ArviZ.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scm_core.arviz_import import arviz
from scm_core.signals.responses import RESPONSE_KEYS, RESPONSES, response

__all__ = ["RunPopulation", "StageRow", "inference_data"]

RESPONSE_UNITS = {k: response(k).unit for k in RESPONSE_KEYS}


@dataclass(frozen=True)
class StageRow:
    """One tempering stage of a run: exponent, acceptance rate, log evidence so far."""

    exponent: float
    acceptance_rate: float
    log_evidence: float

    @classmethod
    def of(cls, *values: float | None) -> StageRow:
        """A row from stored values, None (undefined) read as NaN."""
        return cls(*(math.nan if v is None else float(v) for v in values))


@dataclass(frozen=True)
class RunPopulation:
    """One run: its final population (n, d) with log-likelihoods and log-priors (n,), its
    stage 0 population (the prior draws) and its stages."""

    samples: NDArray[np.float64]
    log_likelihood: NDArray[np.float64]
    log_prior: NDArray[np.float64]
    prior_samples: NDArray[np.float64]
    stages: Sequence[StageRow] = field(default_factory=tuple)


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "unknown"


def _attr(value: Any) -> Any:
    """A NetCDF attribute: JSON text for containers, 0/1 for booleans (NetCDF has none)."""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, dict | list | tuple):
        return json.dumps(value)
    return value


def _stacked(arrays: Sequence[NDArray[np.float64]], what: str) -> NDArray[np.float64]:
    sizes = {a.shape[0] for a in arrays}
    if len(sizes) != 1:
        raise ValueError(f"{what}: runs of different sizes {sorted(sizes)} cannot be chains")
    return np.stack([np.asarray(a, dtype=float) for a in arrays])


def _predictive(
    predictive: Mapping[str, Mapping[str, Sequence[float | None]]] | None, datasets: list[str]
) -> dict[str, NDArray[np.float64]]:
    """{response: (1, draws, dataset)} from predicted draws per dataset name (NaN where a
    dataset or a draw is missing); {} without predictions for these datasets."""
    if not predictive or not datasets or not set(predictive) & set(datasets):
        return {}
    sizes = {len(v) for d in predictive.values() for v in d.values()}
    if len(sizes) != 1:
        raise ValueError(f"posterior_predictive: datasets with {sorted(sizes)} draws")
    n = sizes.pop()
    out = {}
    for r in RESPONSE_KEYS:
        values = np.full((1, n, len(datasets)), np.nan)
        for k, name in enumerate(datasets):
            column = (predictive.get(name) or {}).get(r)
            if column is not None:
                values[0, :, k] = [np.nan if v is None else float(v) for v in column]
        if np.isfinite(values).any():
            out[r] = values
    return out


def _observed_keys(observed: Mapping[str, Mapping[str, Mapping[str, float | None]]]) -> list[str]:
    """The responses of ``observed_data``: F, T and z, and a steered wheel's (Fy) where a
    dataset measured it."""
    measured = {
        r for d in observed.values() for r, v in (d.get("means") or {}).items() if v is not None
    }
    return [r.key for r in RESPONSES if not r.steered or r.key in measured]


def inference_data(
    names: Sequence[str],
    runs: Sequence[RunPopulation],
    *,
    units: Mapping[str, str | None] | None = None,
    observed: Mapping[str, Mapping[str, Mapping[str, float | None]]] | None = None,
    attrs: Mapping[str, Any] | None = None,
    predictive: Mapping[str, Mapping[str, Sequence[float | None]]] | None = None,
):
    """The ``arviz.InferenceData`` of ``runs`` (see the module docstring). ``observed``:
    dataset name -> {"means": {F, T, z}, "standard_errors": {F, T, z}} (SI units; missing or
    None values as NaN). ``predictive``: dataset name -> {response: each draw's value} (one
    chain; needs ``observed`` for its datasets). Raises ValueError for runs of different
    sizes."""
    az = arviz()  # slow to import; only here
    import xarray as xr

    if not runs:
        raise ValueError("no run to export")
    units = dict(units or {})
    post = _stacked([r.samples for r in runs], "posterior")  # (chain, draw, d)
    prior = _stacked([r.prior_samples for r in runs], "prior")
    ll = _stacked([r.log_likelihood for r in runs], "log_likelihood")
    lp = _stacked([r.log_prior for r in runs], "log_prior")
    n_stages = max(len(r.stages) for r in runs)

    def per_stage(attr: str) -> NDArray[np.float64]:
        out = np.full((len(runs), n_stages), np.nan)
        for c, r in enumerate(runs):
            out[c, : len(r.stages)] = [getattr(s, attr) for s in r.stages]
        return out

    sample_stats = {"log_likelihood": ll, "log_prior": lp, "lp": ll + lp}
    coords: dict[str, Any] = {}
    dims: dict[str, list[str]] = {}
    observed_data = None
    shown = _observed_keys(observed or {})
    if observed:
        datasets = list(observed)
        coords["dataset"] = datasets
        observed_data = {}
        for r in shown:
            for key, suffix in (("means", ""), ("standard_errors", "_se")):
                values = [(observed[d].get(key) or {}).get(r) for d in datasets]
                observed_data[r + suffix] = np.array(
                    [np.nan if v is None else float(v) for v in values]
                )
                dims[r + suffix] = ["dataset"]
    posterior_predictive = _predictive(predictive, list(observed or {}))
    if posterior_predictive:
        dims.update({r: ["dataset"] for r in posterior_predictive})
    idata = az.from_dict(
        posterior_predictive=posterior_predictive or None,
        posterior={n: post[:, :, j] for j, n in enumerate(names)},
        prior={n: prior[:, :, j] for j, n in enumerate(names)},
        sample_stats=sample_stats,
        observed_data=observed_data,
        coords=coords,
        dims=dims,
    )
    stage_dims = ("chain", "stage")
    tempering = xr.Dataset(
        {k: (stage_dims, per_stage(k)) for k in ("exponent", "acceptance_rate", "log_evidence")},
        coords={"chain": np.arange(len(runs)), "stage": np.arange(n_stages)},
    )
    idata.add_groups(tempering=tempering)
    for n in names:
        for group in (idata.posterior, idata.prior):
            if units.get(n):
                group[n].attrs["units"] = str(units[n])
    if observed_data is not None:
        for r in shown:
            idata.observed_data[r].attrs["units"] = RESPONSE_UNITS[r]
            idata.observed_data[r + "_se"].attrs["units"] = RESPONSE_UNITS[r]
    for r in posterior_predictive or {}:
        idata.posterior_predictive[r].attrs["units"] = RESPONSE_UNITS[r]
    versions = {p: _version(p) for p in ("scm-calib", "numpy", "arviz")}
    extra = {
        "created_by": "scm-calib",
        "versions": json.dumps(versions),
        **{k: _attr(v) for k, v in (attrs or {}).items()},
    }
    for group in idata.groups():
        getattr(idata, group).attrs.update({k: v for k, v in extra.items() if v is not None})
    return idata
