"""The study's batch likelihood: parameter vectors -> simulated SWTs -> eq. (12)-(15) or (6).

:class:`StudyModel` holds plain data only (dicts of numbers, numpy arrays), so it pickles to
process pools and remote workers; ``StudyModel.log_likelihood_batch`` is what
:func:`scm_core.inference.run_tmcmc` calls.

For a batch X (m, d) and n datasets, the m * n simulator configurations are built (see
:meth:`StudyModel.configs` for the precedence) and run in ONE
:func:`scm_core.simulator.simulate_packed` call (numba threads, rows independent, so results do
not depend on how the rows are batched). The likelihood is the product over datasets and used
responses of eq. (12)-(15) (``normalized``) or eq. (6) (``gaussian``) with the steady means of the
log as x_exp; a response a dataset did not measure (NaN: the CMU data's torque, a straight test's
lateral force) has no term. The prediction-error sigmas are one per response (sigma_F, sigma_T,
sigma_z, sigma_Fy), shared by all datasets: each dataset's residual is scaled by the same sigma, as
the paper's single-dataset likelihood generalises when the model error is assumed the same at every
test condition (give each condition its own study to relax that).

A run that fails (status != "ok") or whose configuration is invalid (e.g. a calibrated R that
makes the grousers too high for the rim: pydantic refuses it) gives log L = -inf and NaN
responses, and its reason (:mod:`scm_core.calibration.failures`) goes with the output; TMCMC
counts those as failed runs, by reason. Nothing is raised for a bad parameter vector.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import ValidationError

from scm_core.inference import portable
from scm_core.inference.likelihood import LOG_SQRT_2PI, log_likelihood_trials
from scm_core.signals import SWTDataset
from scm_core.signals.responses import N_RESPONSES, widened
from scm_core.simulator import (
    RigConfig,
    SoilParams,
    SWTResult,
    WheelGeometry,
    simulate_packed,
    simulate_swt,
)
from scm_core.simulator.cost import run_size
from scm_core.simulator.layout import N_PARAMS, pack
from scm_core.validation_text import one_line

from .case import CALIBRATABLE, RESPONSE_KEYS, RIG_FIELDS, SOIL_FIELDS, WHEEL_FIELDS, CaseDefinition
from .failures import INVALID, failure_of

__all__ = ["DatasetTerms", "StudyModel", "dataset_terms"]


@dataclass(frozen=True)
class DatasetTerms:
    """What the likelihood needs from one dataset: its name, simulator condition keys (W, slip,
    omega, R, b, n_grousers, grouser_height, slip_angle, as available), the steady means (F N,
    T N m, z m, Fy N) with their standard errors (NaN where unknown) and, for a summary of
    repeated trials, their number and sample sds (same units)."""

    name: str
    conditions: dict[str, float | int | str]
    means: tuple[float, ...]  # one per response (RESPONSE_KEYS), NaN where not measured
    content_hash: str = ""
    n_trials: int = 1
    trial_sd: tuple[float, ...] = (np.nan,) * N_RESPONSES
    standard_errors: tuple[float, ...] = (np.nan,) * N_RESPONSES

    def __post_init__(self) -> None:
        """Values given for the first responses only (F, T, z: made before the lateral force
        was declared) read with the others NaN, not measured
        (:func:`~scm_core.signals.responses.widened`)."""
        for name in ("means", "trial_sd", "standard_errors"):
            values = tuple(float(x) for x in widened(getattr(self, name), 1))
            object.__setattr__(self, name, values)

    @property
    def measured(self) -> tuple[str, ...]:
        """The responses (F, T, z, Fy) this dataset measured."""
        return tuple(r for r, x in zip(RESPONSE_KEYS, self.means, strict=True) if np.isfinite(x))

    @property
    def steered(self) -> bool:
        """Whether its wheel runs at a slip angle (the lateral force is then not zero)."""
        return bool(self.conditions.get("slip_angle"))


def dataset_terms(dataset: SWTDataset | DatasetTerms) -> DatasetTerms:
    """Reduce an :class:`~scm_core.signals.SWTDataset` to the plain data the model keeps."""
    if isinstance(dataset, DatasetTerms):
        return dataset
    m = dataset.means
    trials = dataset.n_trials if dataset.source_kind == "summary" and dataset.n_trials else 1
    return DatasetTerms(
        name=dataset.name,
        conditions=dict(dataset.conditions.to_sim_config()),
        means=tuple(float(m.get(r, np.nan)) for r in RESPONSE_KEYS),
        content_hash=dataset.content_hash,
        n_trials=int(trials),
        trial_sd=tuple(
            float(dataset.responses[r].sd) if r in dataset.responses and trials > 1 else np.nan
            for r in RESPONSE_KEYS
        ),
        standard_errors=tuple(
            float(dataset.responses[r].se) if r in dataset.responses else np.nan
            for r in RESPONSE_KEYS
        ),
    )


def build_configs(
    nominal: Mapping[str, Any],
    simulator: Mapping[str, Any],
    conditions: Mapping[str, Any],
    values: Mapping[str, float],
) -> tuple[SoilParams, WheelGeometry, RigConfig]:
    """(soil, wheel, rig) = defaults <- nominal <- simulator <- conditions <- values.

    ``conditions`` are a dataset's simulator keys; its R is the lab's nominal radius, used as
    ``slip_radius`` and as the rim radius unless ``values`` holds R. Without a dataset R the
    slip radius is ``simulator.slip_radius`` / ``nominal.slip_radius`` if given, else the
    nominal (uncalibrated) rim radius. Raises pydantic's ValidationError for invalid values.
    """
    soil: dict[str, Any] = {}
    wheel: dict[str, Any] = {}
    rig: dict[str, Any] = {}
    for source in (nominal, simulator, conditions, values):
        for key, value in source.items():
            if key in SOIL_FIELDS:
                soil[key] = value
            elif key in WHEEL_FIELDS:
                wheel[key] = value
            elif key in RIG_FIELDS:
                rig[key] = value
    lab_radius = conditions.get("R")
    if lab_radius is not None:
        rig["slip_radius"] = lab_radius
        wheel["R"] = values.get("R", lab_radius)
    elif "slip_radius" not in rig:
        rig["slip_radius"] = {**nominal, **simulator}.get("R", WheelGeometry().R)
    return (
        SoilParams.model_validate(soil),
        WheelGeometry.model_validate(wheel),
        RigConfig.model_validate(rig),
    )


class StudyModel:
    """Batch likelihood of a calibration case over one or more SWT datasets (picklable).

    ``names``: calibrated parameters (sample columns); ``response_names``: the columns of the
    responses returned with the likelihood, F/T/z/Fy per dataset (``F[name]``...). Pass
    :class:`~scm_core.signals.SWTDataset` objects or :class:`DatasetTerms`.
    """

    def __init__(self, case: CaseDefinition, datasets: Sequence[SWTDataset | DatasetTerms]):
        if not datasets:
            raise ValueError("a study needs at least one dataset")
        self.names: tuple[str, ...] = case.parameter_names
        self.likelihood: str = case.likelihood
        self.trials: str = case.trials
        self.used: tuple[int, ...] = tuple(RESPONSE_KEYS.index(r) for r in case.responses)
        sig = case.sigma_spec()
        self.sigma_columns: tuple[int | None, ...] = tuple(
            int(sig[RESPONSE_KEYS[i]][1]) if sig[RESPONSE_KEYS[i]][0] == "parameter" else None
            for i in self.used
        )
        self.sigma_fixed: tuple[float, ...] = tuple(
            float(sig[RESPONSE_KEYS[i]][1]) if sig[RESPONSE_KEYS[i]][0] == "fixed" else np.nan
            for i in self.used
        )
        self.physical: tuple[tuple[int, str], ...] = tuple(
            (j, n) for j, n in enumerate(self.names) if CALIBRATABLE[n] in ("soil", "wheel")
        )
        self.nominal: dict[str, Any] = {
            k: v for k, v in case.nominal.items() if CALIBRATABLE.get(k) not in ("sigma", "offset")
        }
        #: measurement offsets (response index, column or None, fixed value)
        self.offsets: tuple[tuple[int, int | None, float], ...] = tuple(
            (
                RESPONSE_KEYS.index(r),
                int(v) if kind == "parameter" else None,
                float(v) if kind == "fixed" else 0.0,
            )
            for r, (kind, v) in case.offset_spec().items()
        )
        self.simulator: dict[str, Any] = dict(case.simulator)
        self.datasets: tuple[DatasetTerms, ...] = tuple(dataset_terms(d) for d in datasets)
        self.x_exp: NDArray[np.float64] = np.array([d.means for d in self.datasets], dtype=float)
        #: per dataset, the positions in ``used`` of the responses it measured: a response a
        #: dataset lacks is absent from its likelihood terms
        self.likelihood_columns: tuple[tuple[int, ...], ...] = tuple(
            tuple(u for u, i in enumerate(self.used) if np.isfinite(self.x_exp[k, i]))
            for k in range(len(self.datasets))
        )
        #: per dataset, the tests its likelihood counts: its trials (``trials = "each"``, a
        #: summary of repeated trials) or one
        self.n_tests: tuple[int, ...] = tuple(
            d.n_trials if self.trials == "each" else 1 for d in self.datasets
        )

    # ------------------------------------------------------------------ configurations

    @property
    def n_datasets(self) -> int:
        return len(self.datasets)

    @property
    def response_names(self) -> tuple[str, ...]:
        return tuple(f"{r}[{d.name}]" for d in self.datasets for r in RESPONSE_KEYS)

    def values(self, theta: ArrayLike) -> dict[str, float]:
        """Calibrated simulator values of one parameter vector (sigmas left out)."""
        theta = np.asarray(theta, dtype=float).reshape(-1)
        return {name: float(theta[j]) for j, name in self.physical}

    def configs(
        self, theta: ArrayLike, dataset: int | SWTDataset | DatasetTerms = 0
    ) -> tuple[SoilParams, WheelGeometry, RigConfig]:
        """Simulator configuration of ``theta`` under the conditions of ``dataset`` (an index
        into the model's datasets, or any dataset; see :func:`build_configs`); raises
        ValidationError for invalid values."""
        d = self.datasets[dataset] if isinstance(dataset, int) else dataset_terms(dataset)
        return build_configs(self.nominal, self.simulator, d.conditions, self.values(theta))

    def config_problem(
        self, theta: ArrayLike, at: str = "the prior medians"
    ) -> tuple[int, str] | None:
        """(dataset index, one-line reason) of the first dataset whose simulator configuration
        cannot be built at ``theta`` (e.g. the prior medians: the study would fail on its first
        batch), or None."""
        for k in range(self.n_datasets):
            try:
                self.configs(theta, k)
            except (ValidationError, ValueError) as exc:
                return k, f"invalid simulator configuration at {at}: {one_line(exc)}"
        return None

    def pack_rows(
        self, X: ArrayLike, datasets: Sequence[int] | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Packed simulator rows (m * n, N_PARAMS) of ``datasets`` (default all, n of them),
        row i * n + k for point i and the k-th of them, and a validity mask (invalid rows are
        zero and must not be run)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        chosen = range(self.n_datasets) if datasets is None else datasets
        m, n = X.shape[0], len(chosen)
        prms = np.zeros((m * n, N_PARAMS))
        valid = np.zeros(m * n, dtype=bool)
        for i in range(m):
            values = self.values(X[i])
            for k, ds in enumerate(chosen):
                d = self.datasets[ds]
                try:
                    cfg = build_configs(self.nominal, self.simulator, d.conditions, values)
                except (ValidationError, ValueError):
                    continue
                prms[i * n + k] = pack(*cfg)
                valid[i * n + k] = True
        return prms, valid

    # ------------------------------------------------------------------ evaluation

    def measurement_offsets(self, theta: ArrayLike) -> dict[str, float]:
        """Measurement offsets of one parameter vector, e.g. {"z": z_offset} [SI]."""
        theta = np.asarray(theta, dtype=float).reshape(-1)
        return {
            RESPONSE_KEYS[i]: float(theta[col]) if col is not None else fixed
            for i, col, fixed in self.offsets
        }

    def simulate_means(
        self, X: ArrayLike, datasets: Sequence[int] | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Steady means (m, n_datasets, k) of the k responses (RESPONSE_KEYS) as the lab would
        measure them (simulated plus the measurement offsets; NaN where a run failed or was
        invalid, or for a dataset not in ``datasets``, default all) and the per-row ok mask
        (m, n_datasets). A dataset's means do not depend on which others are simulated with
        it."""
        means, ok, _ = self.simulate(X, datasets)
        return means, ok

    def simulate(
        self, X: ArrayLike, datasets: Sequence[int] | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.str_]]:
        """:meth:`simulate_means` and why each run failed (m, n_datasets): the simulator's
        status (``bottomed_out``...), :data:`~scm_core.calibration.failures.INVALID` for a
        configuration that could not be built, "" where the run did not fail or was not
        asked for."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        chosen = list(range(self.n_datasets)) if datasets is None else list(datasets)
        m, n = X.shape[0], len(chosen)
        prms, valid = self.pack_rows(X, chosen)
        sim = np.full((m * n, N_RESPONSES), np.nan)
        sim_ok = np.zeros(m * n, dtype=bool)
        why = np.where(valid, "", INVALID).astype(object)
        rows = np.flatnonzero(valid)
        if rows.size:
            batch = simulate_packed(prms[rows])
            sim[rows] = batch.means
            sim_ok[rows] = batch.ok
            why[rows] = [failure_of(status) for status in batch.status]
        sim[~sim_ok] = np.nan
        means = np.full((m, self.n_datasets, N_RESPONSES), np.nan)
        ok = np.zeros((m, self.n_datasets), dtype=bool)
        failure = np.full((m, self.n_datasets), "", dtype=object)
        means[:, chosen] = sim.reshape(m, n, N_RESPONSES)
        ok[:, chosen] = sim_ok.reshape(m, n)
        failure[:, chosen] = why.reshape(m, n)
        for i, col, fixed in self.offsets:
            means[:, :, i] += (X[:, col] if col is not None else fixed)[:, None]
        return means, ok, failure.astype(str)

    def first_failure(self, failure: NDArray[np.str_]) -> NDArray[np.str_]:
        """Per point, the reason of its first failed run in :attr:`part_order` (the order
        early rejection runs the datasets in, so both paths name the same run); "" if none."""
        out = np.full(failure.shape[0], "", dtype=object)
        for k in reversed(self.part_order):
            out = np.where(failure[:, k] != "", failure[:, k], out)
        return out.astype(str)

    def sigmas(self, X: ArrayLike) -> NDArray[np.float64]:
        """Prediction-error sigmas (m, n_used) of the used responses."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        out = np.empty((X.shape[0], len(self.used)))
        for u, (col, fixed) in enumerate(zip(self.sigma_columns, self.sigma_fixed, strict=True)):
            out[:, u] = X[:, col] if col is not None else fixed
        return out

    def log_likelihood_from_means(
        self,
        means: NDArray[np.float64],
        sigma: NDArray[np.float64],
        datasets: Sequence[int] | None = None,
    ) -> NDArray[np.float64]:
        """log L (m,) from simulated means (m, n_datasets, k) and sigmas (m, n_used); summed
        over ``datasets`` (default all) in order (row results independent of m)."""
        total = np.zeros(means.shape[0])
        for k in range(self.n_datasets) if datasets is None else datasets:
            cols = self.likelihood_columns[k]
            if not cols:
                continue
            resp = [self.used[u] for u in cols]
            sd = np.asarray(self.datasets[k].trial_sd, dtype=float)[resp]
            ll = log_likelihood_trials(
                self.likelihood,
                self.x_exp[k, resp],
                sd,
                self.n_tests[k],
                means[:, k, resp],
                sigma[:, cols],
            )
            total = total + np.asarray(ll, dtype=float).reshape(-1)
        return np.where(np.isnan(total), -np.inf, total)

    def log_likelihood_batch(
        self, X: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], None, NDArray[np.str_]]:
        """(log L (m,), responses (m, k * n_datasets), no base density, why each failed run
        failed (m,), see :meth:`first_failure`) for parameter vectors X (m, d)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        means, _, failure = self.simulate(X)
        return (*self._output(X, means), None, self.first_failure(failure))

    def _output(
        self, X: NDArray[np.float64], means: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        ll = self.log_likelihood_from_means(means, self.sigmas(X))
        return ll, means.reshape(X.shape[0], -1)

    # ------------------------------------------------------------ surrogate (delayed acceptance)
    # see scm_core.inference.surrogate.ResponseLikelihood

    @property
    def response_inputs(self) -> tuple[int, ...]:
        """Parameter columns the responses depend on: the simulator's and the offsets."""
        offsets = {col for _, col, _ in self.offsets if col is not None}
        return tuple(sorted({j for j, _ in self.physical} | offsets))

    @property
    def response_outputs(self) -> tuple[int, ...]:
        """The columns of the responses (N_RESPONSES per dataset) its likelihood reads: each
        dataset's measured responses that the case fits."""
        return tuple(
            sorted(
                k * N_RESPONSES + self.used[u]
                for k in range(self.n_datasets)
                for u in self.likelihood_columns[k]
            )
        )

    def from_responses(
        self, X: NDArray[np.float64], R: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The output of :meth:`log_likelihood_batch` had the lab-side means been R
        (m, N_RESPONSES n_datasets; fewer per dataset: stored before the later responses,
        see :func:`~scm_core.signals.responses.widened`)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        R = widened(R, self.n_datasets).reshape(X.shape[0], self.n_datasets, N_RESPONSES)
        return self._output(X, R)

    # ------------------------------------------------------------ parts (early rejection)
    # one part per dataset: see scm_core.inference.early_rejection.PartedLikelihood

    @functools.cached_property
    def part_order(self) -> tuple[int, ...]:
        """Datasets by the size of their run at the case's nominal values (time steps x DEM
        cells), cheapest first; ties and unbuildable configurations keep their order."""
        cost = []
        for d in self.datasets:
            try:
                cfg = build_configs(self.nominal, self.simulator, d.conditions, {})
                size = run_size(pack(*cfg))
                cost.append(float(size.steps) * float(size.grid_cells))
            except (ValidationError, ValueError):
                cost.append(np.inf)
        return tuple(int(k) for k in np.argsort(cost, kind="stable"))

    @property
    def part_in_base(self) -> tuple[bool, ...]:
        return (False,) * self.n_datasets

    def run_part(
        self, X: NDArray[np.float64], k: int
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.str_]]:
        """(log-likelihood term of dataset k (m,), its lab-side means (m, k), why its failed
        runs failed (m,))."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        means, _, failure = self.simulate(X, [k])
        term = self.log_likelihood_from_means(means, self.sigmas(X), [k])
        return term, means[:, k], failure[:, k]

    def part_bound(self, X: NDArray[np.float64], k: int) -> NDArray[np.float64]:
        """Largest log-likelihood term dataset k can have at X (zero residuals); ``inf`` where
        a sigma is not valid (the run decides)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        sigma = self.sigmas(X)[:, list(self.likelihood_columns[k])]
        per = np.full(sigma.shape, -LOG_SQRT_2PI)
        if self.likelihood == "gaussian":
            per = per - portable.log(sigma)
        bound = per.sum(axis=1)
        n = self.n_tests[k]
        if n > 1:  # zero residual of the trial mean; the trials' own scatter stays
            resp = [self.used[u] for u in self.likelihood_columns[k]]
            sd = np.asarray(self.datasets[k].trial_sd, dtype=float)[resp]
            with np.errstate(divide="ignore", invalid="ignore"):
                bound = n * bound - ((n - 1) * sd * sd / (2.0 * sigma * sigma)).sum(axis=1)
        valid = np.all(np.isfinite(sigma) & (sigma > 0), axis=1)
        return np.where(valid, bound, np.inf)

    def assemble(
        self, X: NDArray[np.float64], responses: Sequence[NDArray[np.float64]]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The output of :meth:`log_likelihood_batch` from each dataset's means (m, k)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return self._output(X, np.stack([np.asarray(r, dtype=float) for r in responses], axis=1))

    __call__ = log_likelihood_batch

    def simulate_at(
        self, theta: ArrayLike, dataset: int | SWTDataset | DatasetTerms = 0
    ) -> SWTResult:
        """Full simulated series at ``theta`` under the conditions of ``dataset`` (index or
        dataset; e.g. the MAP sample, to draw the fit); raises ValidationError for an invalid
        configuration."""
        return simulate_swt(*self.configs(theta, dataset))
