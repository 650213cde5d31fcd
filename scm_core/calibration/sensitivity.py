"""Morris screening of the SCM soil parameters on the steady SWT responses (paper section 4.4,
Figure 4).

Factors: the 7 soil parameters of Table 1 (k_c, k_phi, n, c, phi, D_soil, J). As in the paper,
k_c and k_phi are screened jointly by default, through k* = k_c / b_eff + k_phi (eq. 11): the
factor ``k_star`` sets k_phi = k* with k_c = 0, so k* is exact and does not depend on the
footprint width b_eff; the other five factors are screened as they are (6 factors in all).
With ``joint_k=False`` k_c and k_phi are separate factors (7 in all).

Bounds, by precedence: explicit ``bounds``; the case's prior bounds for a calibrated factor
(not for ``k_star``); the defaults :data:`DEFAULT_BOUNDS`: Table 2's parameter space for n, phi
and J, and documented choices for the rest:

* k_star, k_phi: 1e6 .. 1e8 N/m^(n+2), log scale (a decade either side of WF34's 1e7;
  Table 2's 1 .. 1e10 is mostly soils that cannot carry the wheel);
* k_c: -5e5 .. 5e5 N/m^(n+1) (k_c / b_eff up to ~6e6 for b_eff ~ 0.08 m);
* c: 0 .. 1000 Pa (dry sands: c ~ 0; 1 kPa is a cohesive sandy soil);
* D_soil: 0 .. 1e6 N s/m^3 (at SWT penetration rates of a few mm/s, up to ~5 kPa of damping
  stress, a quarter of the static stress).

Responses: the steady means F, T, z of the simulated SWT under one dataset's conditions (and
the lateral force Fy where the dataset's wheel is steered; a straight wheel's is zero). A run
that fails (e.g. bottoms out on a soft, high-n soil) gives NaN; the elementary effects that
touch it are left out and mu, mu*, sigma are taken over the remaining trajectories (counts in
``n_effects``). Indices as in :mod:`scm_core.inference.morris`: linear = mu* / sum mu*,
non-linear = sigma / sum sigma, per response.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import ValidationError

from scm_core.inference.morris import MorrisDesign, morris_analyze, morris_design
from scm_core.jsondoc import finite_or_none
from scm_core.signals import SWTDataset
from scm_core.signals.responses import N_RESPONSES, keys_of, response
from scm_core.simulator import simulate_packed
from scm_core.simulator.layout import N_PARAMS, STATUS_NAMES, pack

from .case import CALIBRATABLE, RESPONSE_KEYS, CaseDefinition
from .failures import INVALID_CODE, failure_counts
from .model import DatasetTerms, build_configs, dataset_terms

__all__ = [
    "DEFAULT_BOUNDS",
    "FACTOR_UNITS",
    "TABLE1_PARAMETERS",
    "MorrisModel",
    "MorrisSettings",
    "SensitivityDesign",
    "SensitivityResult",
    "analyze_sensitivity",
    "run_sensitivity",
    "screening_factors",
    "sensitivity_design",
]

TABLE1_PARAMETERS = ("k_c", "k_phi", "n", "c", "phi", "D_soil", "J")

DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {
    "k_star": (1.0e6, 1.0e8),
    "k_c": (-5.0e5, 5.0e5),
    "k_phi": (1.0e6, 1.0e8),
    "n": (0.8, 2.0),
    "c": (0.0, 1000.0),
    "phi": (11.5, 37.3),
    "D_soil": (0.0, 1.0e6),
    "J": (0.001, 0.1),
}
LOG_SCALE = ("k_star", "k_phi")
FACTOR_UNITS: dict[str, str] = {
    "k_star": "N/m^(n+2)",
    "k_c": "N/m^(n+1)",
    "k_phi": "N/m^(n+2)",
    "n": "-",
    "c": "Pa",
    "phi": "deg",
    "D_soil": "N s/m^3",
    "J": "m/s",
}

MapFn = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]


def screening_factors(
    case: CaseDefinition | None = None,
    joint_k: bool = True,
    bounds: Mapping[str, tuple[float, float]] | None = None,
) -> tuple[tuple[str, ...], NDArray[np.float64], NDArray[np.bool_]]:
    """(names, bounds (d, 2), log_scale (d,)) of the screened factors (see module doc)."""
    names = ("k_star", "n", "c", "phi", "D_soil", "J") if joint_k else TABLE1_PARAMETERS
    bounds = dict(bounds or {})
    unknown = set(bounds) - set(names)
    if unknown:
        raise ValueError(
            f"bounds given for {sorted(unknown)}, which are not screened; factors: "
            f"{', '.join(names)}"
        )
    rows = []
    for name in names:
        if name in bounds:
            lo, hi = bounds[name]
        elif case is not None and name in case.parameters and name != "k_star":
            dist = case.parameters[name].to_distribution()
            lo, hi = dist.lower, dist.upper
        else:
            lo, hi = DEFAULT_BOUNDS[name]
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"bounds of {name}: need finite lower < upper, got {lo!r}, {hi!r}")
        rows.append((float(lo), float(hi)))
    b = np.array(rows, dtype=float)
    log = np.array([n in LOG_SCALE and b[i, 0] > 0 for i, n in enumerate(names)], dtype=bool)
    return names, b, log


class MorrisModel:
    """Picklable ``func_batch``: factor points (m, d) -> (steady means (m, N_RESPONSES)
    [N, N m, m, N] under one dataset's conditions, NaN for failed or invalid runs; status
    codes (m,), see
    :data:`~scm_core.calibration.failures.INVALID_CODE`), rows run in one
    :func:`~scm_core.simulator.simulate_packed` call."""

    def __init__(
        self,
        names: Sequence[str],
        case: CaseDefinition | None,
        dataset: SWTDataset | DatasetTerms,
    ):
        self.names = tuple(names)
        self.nominal = (
            {
                k: v
                for k, v in case.nominal.items()
                if CALIBRATABLE.get(k) not in ("sigma", "offset")
            }
            if case
            else {}
        )
        self.simulator = dict(case.simulator) if case else {}
        self.dataset = dataset_terms(dataset)

    @property
    def keys(self) -> tuple[str, ...]:
        """The responses screened: those the dataset's wheel gives (:func:`keys_of`)."""
        return keys_of(self.dataset.steered)

    def values(self, x: NDArray[np.float64]) -> dict[str, float]:
        out: dict[str, float] = {}
        for name, v in zip(self.names, x, strict=True):
            if name == "k_star":
                out["k_c"] = 0.0
                out["k_phi"] = float(v)
            else:
                out[name] = float(v)
        return out

    def __call__(self, X: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        prms = np.zeros((X.shape[0], N_PARAMS))
        valid = np.zeros(X.shape[0], dtype=bool)
        for i, x in enumerate(X):
            try:
                cfg = build_configs(
                    self.nominal, self.simulator, self.dataset.conditions, self.values(x)
                )
            except (ValidationError, ValueError):
                continue
            prms[i] = pack(*cfg)
            valid[i] = True
        out = np.full((X.shape[0], N_RESPONSES), np.nan)
        status = np.full(X.shape[0], INVALID_CODE, dtype=np.int64)
        rows = np.flatnonzero(valid)
        if rows.size:
            res = simulate_packed(prms[rows])
            means = res.means.copy()
            means[~res.ok] = np.nan
            out[rows] = means
            status[rows] = [STATUS_NAMES.index(s) for s in res.status]
        return out, status


@dataclass(frozen=True, eq=False)
class SensitivityResult:
    """Morris statistics (d, N_RESPONSES) per factor and response F, T, z, Fy, reported for
    ``keys`` (Fy only for a steered wheel); see the module doc."""

    names: tuple[str, ...]
    bounds: NDArray[np.float64]
    log_scale: NDArray[np.bool_]
    mu: NDArray[np.float64]
    mu_star: NDArray[np.float64]
    sigma: NDArray[np.float64]
    linear_index: NDArray[np.float64]
    nonlinear_index: NDArray[np.float64]
    n_effects: NDArray[np.int64]
    points: NDArray[np.float64]
    outputs: NDArray[np.float64]
    r: int
    levels: int
    seed: int
    dataset: str
    status: NDArray[np.int64] | None = None  # per point (see failures.INVALID_CODE)
    keys: tuple[str, ...] = keys_of(steered=False)

    @property
    def n_runs(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_failed(self) -> int:
        reported = self.outputs[:, [RESPONSE_KEYS.index(r) for r in self.keys]]
        return int(np.count_nonzero(~np.all(np.isfinite(reported), axis=1)))

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible (NaN as null)."""

        columns = [(RESPONSE_KEYS.index(r), r) for r in self.keys]

        def table(a: NDArray[np.float64]) -> dict[str, dict[str, float | None]]:
            return {
                resp: {n: finite_or_none(a[i, k]) for i, n in enumerate(self.names)}
                for k, resp in columns
            }

        return {
            "method": "morris",
            "factors": [
                {
                    "name": n,
                    "lower": float(self.bounds[i, 0]),
                    "upper": float(self.bounds[i, 1]),
                    "log_scale": bool(self.log_scale[i]),
                }
                for i, n in enumerate(self.names)
            ],
            "responses": {r: response(r).unit for r in self.keys},
            "r": self.r,
            "levels": self.levels,
            "seed": self.seed,
            "dataset": self.dataset,
            "n_runs": self.n_runs,
            "n_failed_runs": self.n_failed,
            # why they failed (absent for results stored before the reasons were kept)
            **({} if self.status is None else {"failed_runs_by": failure_counts(self.status)}),
            "mu": table(self.mu),
            "mu_star": table(self.mu_star),
            "sigma": table(self.sigma),
            "linear_index": table(self.linear_index),
            "nonlinear_index": table(self.nonlinear_index),
            "n_effects": {
                resp: {n: int(self.n_effects[i, k]) for i, n in enumerate(self.names)}
                for k, resp in columns
            },
        }


def _nan_stats(ee: NDArray[np.float64]):
    """mu, mu*, sigma (ddof 1) and counts over trajectories, ignoring NaN effects."""
    finite = np.isfinite(ee)
    count = finite.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(finite, ee, 0.0)
        mu = z.sum(axis=0) / count
        mu_star = np.abs(z).sum(axis=0) / count
        dev = np.where(finite, ee - mu, 0.0)
        sigma = np.sqrt((dev * dev).sum(axis=0) / (count - 1))
    mu = np.where(count > 0, mu, np.nan)
    mu_star = np.where(count > 0, mu_star, np.nan)
    sigma = np.where(count > 1, sigma, np.nan)
    return mu, mu_star, sigma, count


def _normalise(a: NDArray[np.float64]) -> NDArray[np.float64]:
    s = np.nansum(a, axis=0, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(s > 0, a / s, 0.0)


@dataclass(frozen=True, eq=False)
class SensitivityDesign:
    """A Morris screening, designed but not yet run: the factors and the trajectory points.

    The points (``design.points``, shape (r (d + 1), d)) can be evaluated anywhere, in any
    chunks (a local map, a process pool, Celery work batches): the outputs depend only on the
    point, so :func:`analyze_sensitivity` gives the same result however they were run.
    """

    names: tuple[str, ...]
    bounds: NDArray[np.float64]
    log_scale: NDArray[np.bool_]
    design: MorrisDesign
    seed: int

    @property
    def points(self) -> NDArray[np.float64]:
        return self.design.points

    @property
    def n_points(self) -> int:
        return int(self.design.points.shape[0])

    def factor_box(self) -> dict[str, Any]:
        """The factors as a prior document (``JointPrior.to_dict()`` form: names, uniform or
        log-uniform bounds, units): the columns of the design points."""
        return {
            "parameters": [
                {
                    "name": n,
                    "dist": "log_uniform" if self.log_scale[i] else "uniform",
                    "lower": float(self.bounds[i, 0]),
                    "upper": float(self.bounds[i, 1]),
                    "unit": FACTOR_UNITS.get(n),
                }
                for i, n in enumerate(self.names)
            ]
        }


@dataclass(frozen=True)
class MorrisSettings:
    """A Morris screening's design: ``r`` trajectories on a grid of ``levels`` (even) levels,
    seeded; k_c and k_phi screened jointly through k* (eq. 11) unless not ``joint_k``;
    ``bounds`` {factor: (lower, upper)} over the case's priors and the defaults."""

    r: int = 20
    levels: int = 4
    seed: int = 0
    joint_k: bool = True
    bounds: Mapping[str, tuple[float, float]] | None = None


def sensitivity_design(
    case: CaseDefinition | None = None, morris: MorrisSettings = MorrisSettings()
) -> SensitivityDesign:
    """The factors (see :func:`screening_factors`) and the Morris trajectories of ``morris``.
    Raises ValueError naming the bad bound, ``r`` or ``levels``."""
    names, b, log = screening_factors(case, morris.joint_k, morris.bounds)
    _, design = morris_design(
        b, r=morris.r, levels=morris.levels, seed=morris.seed, names=names, log_scale=log
    )
    return SensitivityDesign(
        names=names, bounds=b, log_scale=log, design=design, seed=int(morris.seed)
    )


def analyze_sensitivity(
    design: SensitivityDesign,
    outputs: ArrayLike,
    dataset: str = "",
    status: ArrayLike | None = None,
    keys: tuple[str, ...] = keys_of(steered=False),
) -> SensitivityResult:
    """Morris statistics from the outputs (n_points, N_RESPONSES) of the design's points, in
    order (NaN rows for failed runs: the elementary effects that touch them are left out);
    ``status``: the runs' status codes, kept to say why runs failed; ``keys``: the responses
    reported (:attr:`MorrisModel.keys`)."""
    Y = np.asarray(outputs, dtype=float)
    if Y.shape != (design.n_points, N_RESPONSES):
        raise ValueError(
            f"outputs have shape {Y.shape}, expected ({design.n_points}, {N_RESPONSES})"
        )
    ee = morris_analyze(design.design, Y).ee  # NaN where a run failed
    mu, mu_star, sigma, count = _nan_stats(ee)
    return SensitivityResult(
        names=design.names,
        bounds=design.bounds,
        log_scale=design.log_scale,
        mu=mu,
        mu_star=mu_star,
        sigma=sigma,
        linear_index=_normalise(mu_star),
        nonlinear_index=_normalise(sigma),
        n_effects=count.astype(np.int64),
        points=design.points,
        outputs=Y,
        r=design.design.r,
        levels=design.design.levels,
        seed=design.seed,
        dataset=dataset,
        status=None if status is None else np.asarray(status, dtype=np.int64),
        keys=tuple(keys),
    )


def run_sensitivity(
    dataset: SWTDataset | DatasetTerms,
    case: CaseDefinition | None = None,
    morris: MorrisSettings = MorrisSettings(),
    map: MapFn = map,
    batch_size: int | None = None,
) -> SensitivityResult:
    """Morris screening (``morris``: trajectories, grid, seed, bounds) of the soil parameters
    under the conditions of ``dataset``, with the case's nominal values and simulator
    settings."""
    design = sensitivity_design(case, morris)
    model = MorrisModel(design.names, case, dataset)
    points = design.points
    n = points.shape[0]
    size = n if batch_size is None else int(batch_size)
    chunks = [points[i : i + size] for i in range(0, n, size)]
    runs = list(map(model, chunks))
    Y = np.concatenate([np.asarray(y) for y, _ in runs], axis=0)
    status = np.concatenate([s for _, s in runs])
    return analyze_sensitivity(design, Y, model.dataset.name, status, model.keys)
