"""Posterior predictions across test conditions (DESIGN section 4; paper section 5.3).

Draws of a finished study's posterior are simulated under other test conditions (held-out
datasets, a sweep of the slip or the slip angle, a force map over both). Per condition and
response the result gives the median and the central 95 % band of the simulated steady means
(the parameter uncertainty), the same with the study's
prediction-error noise added (sigma_F, sigma_T, sigma_z, sigma_Fy of each draw: where a new
measurement is expected to fall), and, where the condition has a measurement, the measured value
and whether it lies inside the bands. The responses predicted are F, T and z, and the lateral
force Fy where the case fits it, a condition measured it or a condition is steered
(:func:`predicted_keys`): a straight wheel's is zero.

Deterministic for a seed: the draws are chosen with ``SeedSequence([seed, 0])`` and the noise
with ``SeedSequence([seed, 1])``; every simulation is independent of its batch, so any ``map``
(processes, workers) gives identical numbers. Pure: no file I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.jsondoc import finite_or_none
from scm_core.signals import SWTDataset
from scm_core.signals.responses import N_FIRST, N_RESPONSES, keys_for
from scm_core.slip import SlipError, resolve_speeds

from .case import RESPONSE_KEYS, SIGMA_NAMES, CaseDefinition
from .model import DatasetTerms, StudyModel, dataset_terms

__all__ = [
    "Band",
    "ConditionPrediction",
    "ResponsePrediction",
    "choose_draws",
    "map_targets",
    "predict",
    "predicted_keys",
    "prediction_draws",
    "summarize_predictions",
    "sweep_loads",
    "sweep_targets",
]

MapFn = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]
LEVEL = 0.95


@dataclass(frozen=True)
class Band:
    """Median and central 95 % interval [lo, hi] of a response over the posterior draws (SI)."""

    median: float
    lo: float
    hi: float

    @classmethod
    def of(cls, x: NDArray[np.float64]) -> Band:
        x = x[np.isfinite(x)]
        if x.size == 0:
            return cls(math.nan, math.nan, math.nan)
        q = np.quantile(x, [0.5, (1 - LEVEL) / 2, (1 + LEVEL) / 2])
        return cls(float(q[0]), float(q[1]), float(q[2]))

    def contains(self, value: float) -> bool:
        return bool(self.lo <= value <= self.hi)

    def to_dict(self) -> dict[str, float | None]:
        return {k: finite_or_none(getattr(self, k)) for k in ("median", "lo", "hi")}


@dataclass(frozen=True)
class ResponsePrediction:
    """One response under one condition: ``simulated`` band of the steady means, ``predictive``
    band with the prediction-error noise (None if the study has no sigma for the response),
    the ``measured`` mean if the condition has one, and whether it lies inside each band.
    ``draws``: the value of each posterior draw the bands summarise (with the noise where the
    study has a sigma; NaN for a failed run): ArviZ's ``posterior_predictive``."""

    response: str
    simulated: Band
    predictive: Band | None
    measured: float | None = None
    draws: tuple[float, ...] = ()

    @property
    def inside_predictive(self) -> bool | None:
        if self.measured is None or self.predictive is None:
            return None
        return self.predictive.contains(self.measured)

    @property
    def inside_simulated(self) -> bool | None:
        return None if self.measured is None else self.simulated.contains(self.measured)

    def to_dict(self, draws: bool = False) -> dict[str, Any]:
        """The bands (and with ``draws`` every draw's value, None for a failed run)."""
        doc = {
            "simulated": self.simulated.to_dict(),
            "predictive": None if self.predictive is None else self.predictive.to_dict(),
            "measured": finite_or_none(self.measured),
            "inside_predictive": self.inside_predictive,
            "inside_simulated": self.inside_simulated,
        }
        if draws:
            doc["draws"] = [finite_or_none(x) for x in self.draws]
        return doc


@dataclass(frozen=True)
class ConditionPrediction:
    """Predictions under one test condition (a dataset or a sweep point)."""

    name: str
    conditions: dict[str, Any]
    slip_symmetric: float | None
    n_draws: int
    n_failed: int
    responses: dict[str, ResponsePrediction] = field(default_factory=dict)
    role: str = "predicted"  # "calibration" (the study used it), "predicted", "sweep"

    def to_dict(self, draws: bool = False) -> dict[str, Any]:
        """As JSON; ``draws``: with every draw's value per response (see ResponsePrediction)."""
        return {
            "name": self.name,
            "role": self.role,
            "conditions": dict(self.conditions),
            "slip_symmetric": finite_or_none(self.slip_symmetric),
            "n_draws": self.n_draws,
            "n_failed": self.n_failed,
            "responses": {r: p.to_dict(draws) for r, p in self.responses.items()},
        }


def choose_draws(n_available: int, n_draws: int, seed: int) -> NDArray[np.int64]:
    """Indices of ``n_draws`` posterior samples: without replacement when there are enough,
    else every sample once and the rest with replacement (sorted, reproducible)."""
    if n_available < 1:
        raise ValueError("the posterior has no samples")
    if n_draws < 1:
        raise ValueError(f"draws must be >= 1, got {n_draws}")
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0]))
    if n_draws <= n_available:
        idx = rng.choice(n_available, size=n_draws, replace=False)
    else:
        extra = rng.choice(n_available, size=n_draws - n_available, replace=True)
        idx = np.concatenate([np.arange(n_available), extra])
    return np.sort(idx).astype(np.int64)


def _slip_symmetric(conditions: dict[str, Any]) -> float | None:
    s = conditions.get("slip")
    if s is None:
        return None
    if conditions.get("slip_convention") == "symmetric" or s >= 0:
        return float(s)
    return float(s) / (1.0 - float(s))


def sweep_loads(datasets: Sequence[DatasetTerms]) -> tuple[NDArray, NDArray] | None:
    """(symmetric slips ascending, loads W [N]) of the datasets that state both, or None if
    fewer than two do (the sweep then keeps its template's load)."""
    pts = sorted(
        (s, float(d.conditions["W"]))
        for d in datasets
        if d.conditions.get("W") is not None and (s := _slip_symmetric(d.conditions)) is not None
    )
    if len({s for s, _ in pts}) < 2:
        return None
    slips = np.array([s for s, _ in pts])
    loads = np.array([w for _, w in pts])
    return slips, loads


def sweep_targets(
    template: DatasetTerms,
    values: Sequence[float],
    loads: tuple[NDArray, NDArray] | None = None,
    key: str = "slip",
) -> list[DatasetTerms]:
    """Conditions of ``template`` with ``key`` replaced by each of ``values``, the rest kept.

    ``key`` "slip": the symmetric lab slip (-1 = locked) at the template's carriage speed (as a
    lab sweeps the wheel speed); without a known carriage speed, the rig's default speeds for a
    slip. ``loads`` (from :func:`sweep_loads`): the load W at each sweep slip is interpolated
    linearly between the datasets' measured loads (held constant beyond the outermost ones), as
    on a rig whose normal load is not commanded; otherwise the template's load.
    ``key`` "slip_angle": the slip angle [deg] at the template's kinematics and load (``loads``
    does not apply). Points are named "slip 0.3", "slip_angle 30"."""
    if key == "slip_angle":
        return [
            DatasetTerms(
                name=f"slip_angle {a:.4g}",
                conditions={**template.conditions, "slip_angle": float(a)},
                means=(math.nan,) * N_RESPONSES,
            )
            for a in values
        ]
    if key != "slip":
        raise ValueError(f"a sweep varies slip or slip_angle, not {key!r}")
    cond = dict(template.conditions)
    v = cond.get("carriage_speed")
    if v is None and cond.get("omega") is not None and cond.get("R") is not None:
        try:
            v, _, _ = resolve_speeds(
                cond.get("slip"),
                cond.get("slip_convention"),
                None,
                cond["omega"] * cond["R"],
                default_speed=1.0,
            )
        except SlipError:
            v = None
    base = {k: x for k, x in cond.items() if k not in ("slip", "slip_convention", "omega")}
    if v is not None:
        base["carriage_speed"] = v
    unmeasured = (math.nan,) * N_RESPONSES
    out = []
    for s in values:
        cond_s = {**base, "slip": float(s), "slip_convention": "symmetric"}
        if loads is not None:
            cond_s["W"] = float(np.interp(s, loads[0], loads[1]))
        out.append(DatasetTerms(name=f"slip {s:.4g}", conditions=cond_s, means=unmeasured))
    return out


def map_targets(
    template: DatasetTerms, slips: Sequence[float], slip_angles: Sequence[float]
) -> list[DatasetTerms]:
    """A force map's grid: ``template``'s conditions at every symmetric slip of ``slips`` (as
    :func:`sweep_targets` sets them) and slip angle [deg] of ``slip_angles``, slip-major (all
    angles of the first slip first), at the template's load; named "slip 0.3, slip_angle 30"."""
    return [
        DatasetTerms(
            name=f"{t.name}, slip_angle {a:.4g}",
            conditions={**t.conditions, "slip_angle": float(a)},
            means=t.means,
        )
        for t in sweep_targets(template, slips)
        for a in slip_angles
    ]


def predicted_keys(case: CaseDefinition, targets: Sequence[DatasetTerms]) -> tuple[str, ...]:
    """The responses a prediction gives, in :data:`RESPONSES` order: those every run gives
    (F, T, z), and a steered wheel's (Fy) where the case fits it, a target measured it or a
    target is steered."""
    measured = (t.measured for t in targets)
    return keys_for(any(t.steered for t in targets), case.responses, *measured)


def prediction_draws(
    case: CaseDefinition, samples: ArrayLike, draws: int, seed: int
) -> NDArray[np.float64]:
    """The ``draws`` posterior samples (rows of ``samples``, in the case's parameter order)
    a prediction simulates (:func:`choose_draws`)."""
    X = np.atleast_2d(np.asarray(samples, dtype=float))
    if X.shape[1] != len(case.parameters):
        raise ValueError(
            f"samples have {X.shape[1]} columns, the case has {len(case.parameters)} parameters"
        )
    return X[choose_draws(X.shape[0], draws, seed)]


def summarize_predictions(
    case: CaseDefinition,
    targets: Sequence[DatasetTerms],
    draws: NDArray[np.float64],
    means: NDArray[np.float64],
    ok: NDArray[np.bool_],
    seed: int,
    roles: Sequence[str] | None = None,
) -> list[ConditionPrediction]:
    """Bands per target and response (:func:`predicted_keys`) from the simulated steady
    ``means`` (draws, targets, N_RESPONSES) of ``draws`` (whether each run succeeded: ``ok``
    (draws, targets)); the prediction noise is drawn from ``SeedSequence([seed, 1])``: one
    normal per draw, target and response, first for the responses declared at first (F, T,
    z), then for the later ones, so that those are the numbers they always were."""
    sigma = _sigmas(case, draws)  # response -> (draws,) or None
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    size = (draws.shape[0], len(targets))
    first = rng.standard_normal((*size, N_FIRST))
    noise = np.concatenate([first, rng.standard_normal((*size, N_RESPONSES - N_FIRST))], axis=2)
    keys = predicted_keys(case, targets)
    out = []
    for k, t in enumerate(targets):
        responses = {}
        for i, r in enumerate(RESPONSE_KEYS):
            if r not in keys:
                continue
            sim = means[:, k, i]
            pred = None
            values = sim
            if sigma[r] is not None:
                values = sim + sigma[r] * noise[:, k, i]
                pred = Band.of(values)
            measured = t.means[i] if math.isfinite(t.means[i]) else None
            responses[r] = ResponsePrediction(
                r, Band.of(sim), pred, measured, tuple(float(v) for v in values)
            )
        out.append(
            ConditionPrediction(
                name=t.name,
                conditions=dict(t.conditions),
                slip_symmetric=_slip_symmetric(t.conditions),
                n_draws=int(draws.shape[0]),
                n_failed=int((~ok[:, k]).sum()),
                responses=responses,
                role=roles[k] if roles is not None else "predicted",
            )
        )
    return out


def predict(
    case: CaseDefinition,
    samples: ArrayLike,
    targets: Sequence[SWTDataset | DatasetTerms],
    draws: int = 200,
    seed: int = 0,
    map: MapFn = map,
    batch_size: int = 50,
    roles: Sequence[str] | None = None,
) -> list[ConditionPrediction]:
    """Simulate ``draws`` posterior samples (rows of ``samples``, in the case's parameter order)
    under each target's test conditions; one :class:`ConditionPrediction` per target. The
    same numbers for any ``map`` and ``batch_size``: each draw's runs depend on the draw only."""
    terms = [dataset_terms(t) for t in targets]
    if not terms:
        return []
    Xd = prediction_draws(case, samples, draws, seed)
    model = StudyModel(case, terms)
    chunks = [Xd[i : i + batch_size] for i in range(0, Xd.shape[0], batch_size)]
    parts = list(map(model.simulate_means, chunks))
    means = np.concatenate([p[0] for p in parts], axis=0)  # (draws, targets, N_RESPONSES)
    ok = np.concatenate([p[1] for p in parts], axis=0)
    return summarize_predictions(case, terms, Xd, means, ok, seed, roles)


def _sigmas(case: CaseDefinition, X: NDArray[np.float64]) -> dict[str, NDArray | None]:
    """Prediction-error sigma per response and draw: the calibrated column, the nominal value,
    or None where the case has neither (no predictive band)."""
    names = case.parameter_names
    out: dict[str, NDArray | None] = {}
    for r in RESPONSE_KEYS:
        s = SIGMA_NAMES[r]
        if s in names:
            out[r] = X[:, names.index(s)]
        elif s in case.nominal:
            out[r] = np.full(X.shape[0], float(case.nominal[s]))
        else:
            out[r] = None
    return out
