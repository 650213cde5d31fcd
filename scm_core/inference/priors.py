"""Prior distributions for calibrated parameters (paper section 4.5, Table 2).

Each univariate distribution is an immutable value with ``logpdf``, ``sample``, ``ppf``, ``lower``,
``upper`` and a JSON-friendly ``to_dict``/``from_dict``. :class:`JointPrior` combines named,
independent parameters in a fixed order; that order is the column order of every sample array in
:mod:`scm_core.inference`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.inference import portable

__all__ = [
    "LOG_SCALE_KINDS",
    "TABLE2_NOMINAL",
    "Distribution",
    "JointPrior",
    "LogNormal",
    "LogUniform",
    "TruncatedNormal",
    "Uniform",
    "distribution_from_dict",
    "table2_prior",
]


def _check_finite(cls_name: str, **values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f"{cls_name}: '{name}' must be finite, got {value!r}")


def _check_order(cls_name: str, lower: float, upper: float) -> None:
    if not lower < upper:
        raise ValueError(
            f"{cls_name}: 'upper' ({upper!r}) must be greater than 'lower' ({lower!r})"
        )


def _check_kind(cls_name: str, data: Mapping[str, Any], kind: str) -> None:
    if data.get("dist") != kind:
        raise ValueError(f"{cls_name}.from_dict: 'dist' must be {kind!r}, got {data.get('dist')!r}")


class _Serial:
    """``to_dict``/``from_dict`` from a distribution's init fields: {"dist": kind, field: value}."""

    kind: ClassVar[str]

    def to_dict(self) -> dict[str, Any]:
        names = [f.name for f in fields(self) if f.init]  # type: ignore[arg-type]
        return {"dist": self.kind, **{n: getattr(self, n) for n in names}}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Any:
        _check_kind(cls.__name__, data, cls.kind)
        return cls(**{f.name: data[f.name] for f in fields(cls) if f.init})  # type: ignore[arg-type]


@dataclass(frozen=True)
class Uniform(_Serial):
    """Uniform density on the closed interval [lower, upper]."""

    lower: float
    upper: float
    kind: ClassVar[str] = "uniform"

    def __post_init__(self) -> None:
        object.__setattr__(self, "lower", float(self.lower))
        object.__setattr__(self, "upper", float(self.upper))
        _check_finite("Uniform", lower=self.lower, upper=self.upper)
        _check_order("Uniform", self.lower, self.upper)

    def logpdf(self, x: ArrayLike) -> NDArray[np.float64]:
        """Log density; -inf outside [lower, upper]."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lower) & (x <= self.upper)
        return np.where(inside, -math.log(self.upper - self.lower), -np.inf)

    def ppf(self, u: ArrayLike) -> NDArray[np.float64]:
        """Quantile function for u in [0, 1]."""
        u = np.asarray(u, dtype=float)
        return self.lower + u * (self.upper - self.lower)

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> NDArray[np.float64]:
        """Independent draws."""
        return self.ppf(rng.random(size))


@dataclass(frozen=True)
class TruncatedNormal(_Serial):
    """Normal(mean, sd) truncated to [lower, upper] (scipy.stats.truncnorm)."""

    mean: float
    sd: float
    lower: float
    upper: float
    kind: ClassVar[str] = "truncated_normal"

    def __post_init__(self) -> None:
        for name in ("mean", "sd", "lower", "upper"):
            object.__setattr__(self, name, float(getattr(self, name)))
        _check_finite(
            "TruncatedNormal", mean=self.mean, sd=self.sd, lower=self.lower, upper=self.upper
        )
        if not self.sd > 0:
            raise ValueError(f"TruncatedNormal: 'sd' must be > 0, got {self.sd!r}")
        _check_order("TruncatedNormal", self.lower, self.upper)

    @cached_property
    def _standard(self) -> tuple[float, float, bool]:
        """(lower, upper) standardised, and whether they lie in the upper tail (a >= 0), where
        the normal's survival function keeps the digits its distribution function loses."""
        a = (self.lower - self.mean) / self.sd
        b = (self.upper - self.mean) / self.sd
        return a, b, a >= 0.0

    @cached_property
    def _ends(self) -> tuple[float, float]:
        """Phi at the ends (Phi(-.) of their negatives in the upper tail): scipy.special's
        ndtr, compiled code whose bits do not depend on the CPU (:mod:`.portable`)."""
        from scipy.special import ndtr

        a, b, upper_tail = self._standard
        if upper_tail:
            return float(ndtr(-a)), float(ndtr(-b))
        return float(ndtr(a)), float(ndtr(b))

    @cached_property
    def _log_norm(self) -> float:
        """log(sd sqrt(2 pi) Z), Z the normal mass in [a, b] (so that logpdf is a closed form
        equal to scipy's truncnorm.logpdf)."""
        lo, hi = self._ends
        mass = abs(hi - lo)
        return math.log(self.sd) + 0.5 * math.log(2.0 * math.pi) + math.log(mass)

    def logpdf(self, x: ArrayLike) -> NDArray[np.float64]:
        """Log density; -inf outside [lower, upper]."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lower) & (x <= self.upper)
        z = (x - self.mean) / self.sd
        return np.where(inside, -0.5 * z * z - self._log_norm, -np.inf)

    def ppf(self, u: ArrayLike) -> NDArray[np.float64]:
        """Quantile function for u in [0, 1]: the normal's inverse at Phi(a) + u (Phi(b) -
        Phi(a)), through the survival function in the upper tail (scipy.special's ndtri; the
        bits do not depend on the CPU)."""
        from scipy.special import ndtri

        u = np.asarray(u, dtype=float)
        lo, hi = self._ends
        _, _, upper_tail = self._standard
        p = lo + u * (hi - lo)
        z = -ndtri(p) if upper_tail else ndtri(p)
        x = np.clip(self.mean + self.sd * z, self.lower, self.upper)
        # the ends exactly (ndtri is not exact in a far tail, ~1e-19)
        return np.where(u <= 0.0, self.lower, np.where(u >= 1.0, self.upper, x))

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> NDArray[np.float64]:
        """Independent draws (inverse-CDF of ``rng.random``)."""
        return self.ppf(rng.random(size))


@dataclass(frozen=True)
class LogUniform(_Serial):
    """Log-uniform density 1 / (x log(upper/lower)) on [lower, upper], lower > 0.

    Useful for moduli spanning decades (e.g. k_phi).
    """

    lower: float
    upper: float
    kind: ClassVar[str] = "log_uniform"

    def __post_init__(self) -> None:
        object.__setattr__(self, "lower", float(self.lower))
        object.__setattr__(self, "upper", float(self.upper))
        _check_finite("LogUniform", lower=self.lower, upper=self.upper)
        if not self.lower > 0:
            raise ValueError(f"LogUniform: 'lower' must be > 0, got {self.lower!r}")
        _check_order("LogUniform", self.lower, self.upper)

    def logpdf(self, x: ArrayLike) -> NDArray[np.float64]:
        """Log density; -inf outside [lower, upper]."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lower) & (x <= self.upper)
        log_norm = math.log(math.log(self.upper / self.lower))
        safe = np.where(inside, x, self.lower)
        return np.where(inside, -portable.log(safe) - log_norm, -np.inf)

    def ppf(self, u: ArrayLike) -> NDArray[np.float64]:
        """Quantile function for u in [0, 1]."""
        u = np.asarray(u, dtype=float)
        lo, hi = math.log(self.lower), math.log(self.upper)
        return np.clip(portable.exp(lo + u * (hi - lo)), self.lower, self.upper)

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> NDArray[np.float64]:
        """Independent draws."""
        return self.ppf(rng.random(size))


@dataclass(frozen=True)
class LogNormal(_Serial):
    """Log-normal density truncated to [lower, upper], lower > 0: log x ~ Normal(log median,
    log factor).

    ``factor`` is the geometric standard deviation (> 1): one sd either side of the median is
    median / factor .. median * factor, 95 % of the untruncated mass within factor^1.96. The prior
    of a modulus measured to "a factor of two" (bevameter moduli, paper section 1).
    """

    median: float
    factor: float
    lower: float
    upper: float
    kind: ClassVar[str] = "log_normal"
    _log: TruncatedNormal = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("median", "factor", "lower", "upper"):
            object.__setattr__(self, name, float(getattr(self, name)))
        _check_finite(
            "LogNormal", median=self.median, factor=self.factor, lower=self.lower, upper=self.upper
        )
        if not self.median > 0:
            raise ValueError(f"LogNormal: 'median' must be > 0, got {self.median!r}")
        if not self.factor > 1:
            raise ValueError(f"LogNormal: 'factor' must be > 1, got {self.factor!r}")
        if not self.lower > 0:
            raise ValueError(f"LogNormal: 'lower' must be > 0, got {self.lower!r}")
        _check_order("LogNormal", self.lower, self.upper)
        log = TruncatedNormal(
            math.log(self.median), math.log(self.factor), math.log(self.lower), math.log(self.upper)
        )
        object.__setattr__(self, "_log", log)

    def logpdf(self, x: ArrayLike) -> NDArray[np.float64]:
        """Log density (the normal's in log x, less log x); -inf outside [lower, upper]."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.lower) & (x <= self.upper)
        safe = np.where(inside, x, self.lower)
        log_safe = portable.log(safe)
        log_x = np.clip(log_safe, self._log.lower, self._log.upper)
        return np.where(inside, self._log.logpdf(log_x) - log_safe, -np.inf)

    def ppf(self, u: ArrayLike) -> NDArray[np.float64]:
        """Quantile function for u in [0, 1]."""
        return np.clip(portable.exp(self._log.ppf(u)), self.lower, self.upper)

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> NDArray[np.float64]:
        """Independent draws (inverse-CDF of ``rng.random``)."""
        return self.ppf(rng.random(size))


Distribution = Uniform | TruncatedNormal | LogUniform | LogNormal

LOG_SCALE_KINDS = frozenset({"log_uniform", "log_normal"})
"""Distribution kinds whose parameter is shown and fitted on a log axis."""

_KINDS: dict[str, type[Distribution]] = {
    "uniform": Uniform,
    "truncated_normal": TruncatedNormal,
    "normal": TruncatedNormal,
    "log_uniform": LogUniform,
    "loguniform": LogUniform,
    "log_normal": LogNormal,
    "lognormal": LogNormal,
}


def distribution_from_dict(data: Mapping[str, Any]) -> Distribution:
    """Build a univariate distribution from ``{"dist": kind, ...}``.

    Kinds: "uniform", "truncated_normal" (alias "normal"), "log_uniform" (alias "loguniform"),
    "log_normal" (alias "lognormal").
    """
    kind = data.get("dist")
    if kind not in _KINDS:
        raise ValueError(f"'dist' must be one of {sorted(_KINDS)}, got {kind!r}")
    cls = _KINDS[kind]
    return cls.from_dict({**data, "dist": cls.kind})


@dataclass(frozen=True)
class JointPrior:
    """Product of independent named univariate priors, in insertion order.

    ``dists`` maps parameter name to distribution; ``units`` optionally maps name to a unit string.
    All arrays of parameter vectors use this order along their last axis.
    """

    dists: Mapping[str, Distribution]
    units: Mapping[str, str] | None = None
    _bounds: NDArray[np.float64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.dists) == 0:
            raise ValueError("JointPrior: 'dists' must not be empty")
        for name, dist in self.dists.items():
            if not isinstance(dist, Distribution):
                raise ValueError(f"JointPrior: 'dists[{name!r}]' is not a distribution: {dist!r}")
        object.__setattr__(self, "dists", dict(self.dists))
        units = dict(self.units or {})
        unknown = set(units) - set(self.dists)
        if unknown:
            raise ValueError(f"JointPrior: 'units' names unknown parameters {sorted(unknown)}")
        object.__setattr__(self, "units", units)
        bounds = np.array([[d.lower, d.upper] for d in self.dists.values()], dtype=float)
        bounds.flags.writeable = False
        object.__setattr__(self, "_bounds", bounds)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.dists)

    @property
    def dim(self) -> int:
        return len(self.dists)

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(d, 2) array of [lower, upper] per parameter."""
        return self._bounds.copy()

    def _as_2d(self, X: ArrayLike) -> tuple[NDArray[np.float64], bool]:
        X = np.asarray(X, dtype=float)
        single = X.ndim == 1
        X2 = X.reshape(1, -1) if single else X
        if X2.ndim != 2 or X2.shape[1] != self.dim:
            raise ValueError(f"expected shape (n, {self.dim}) or ({self.dim},), got {X.shape}")
        return X2, single

    def sample(self, rng: np.random.Generator, n: int) -> NDArray[np.float64]:
        """(n, d) independent draws; columns drawn in parameter order from the same ``rng``."""
        return np.column_stack([dist.sample(rng, n) for dist in self.dists.values()])

    def log_pdf(self, X: ArrayLike) -> NDArray[np.float64] | float:
        """Joint log density of (n, d) rows -> (n,), or of one (d,) vector -> float.

        Columns are summed in parameter order (deterministic, independent of n).
        """
        X2, single = self._as_2d(X)
        total = np.zeros(X2.shape[0])
        for j, dist in enumerate(self.dists.values()):
            total = total + dist.logpdf(X2[:, j])
        return float(total[0]) if single else total

    def in_support(self, X: ArrayLike) -> NDArray[np.bool_] | bool:
        """True where every coordinate lies in its [lower, upper] (NaN is outside)."""
        pts, single = self._as_2d(X)
        b = self._bounds
        inside = np.all((pts >= b[:, 0]) & (pts <= b[:, 1]), axis=1)
        return bool(inside[0]) if single else inside

    def ppf(self, U: ArrayLike) -> NDArray[np.float64]:
        """Map points of the unit cube (n, d) to parameter space, column by column."""
        U2, single = self._as_2d(U)
        X = np.column_stack([d.ppf(U2[:, j]) for j, d in enumerate(self.dists.values())])
        return X[0] if single else X

    def to_dict(self) -> dict[str, Any]:
        """``{"parameters": [{"name", "unit"?, "dist", ...}, ...]}`` (order preserved)."""
        params = []
        for name, dist in self.dists.items():
            entry: dict[str, Any] = {"name": name}
            if name in self.units:
                entry["unit"] = self.units[name]
            entry.update(dist.to_dict())
            params.append(entry)
        return {"parameters": params}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> JointPrior:
        params = data.get("parameters")
        if not isinstance(params, list) or not params:
            raise ValueError("JointPrior.from_dict: 'parameters' must be a non-empty list")
        dists: dict[str, Distribution] = {}
        units: dict[str, str] = {}
        for entry in params:
            entry = dict(entry)
            name = entry.pop("name", None)
            if not isinstance(name, str) or not name:
                raise ValueError("JointPrior.from_dict: every parameter needs a 'name'")
            if name in dists:
                raise ValueError(f"JointPrior.from_dict: duplicate 'name' {name!r}")
            unit = entry.pop("unit", None)
            if unit is not None:
                units[name] = str(unit)
            dists[name] = distribution_from_dict(entry)
        return cls(dists, units)


TABLE2_NOMINAL: dict[str, float] = {"J": 0.001, "R": 0.125}
"""Table 2 nominal values (J in m/s, R in m) used when a parameter is not calibrated."""

_TABLE2: dict[str, tuple[Distribution, str]] = {
    "k_c": (Uniform(-1e9, 1e9), "N/m^(n+1)"),
    "k_phi": (Uniform(1.0, 1e10), "N/m^(n+2)"),
    "n": (TruncatedNormal(1.1, 0.2, 0.8, 2.0), "-"),
    "phi": (TruncatedNormal(30.0, 5.7, 11.5, 37.3), "deg"),
    "J": (Uniform(0.001, 0.1), "m/s"),
    "R": (Uniform(0.125, 0.155), "m"),
    "sigma_F": (Uniform(0.0, 5.0), "N"),
    "sigma_T": (Uniform(0.0, 10.0), "N m"),
    "sigma_z": (Uniform(0.0, 0.005), "m"),
}

_CASES: dict[str, tuple[str, ...]] = {
    "1": ("k_c", "k_phi", "n", "phi", "J", "sigma_F", "sigma_T", "sigma_z"),
    "2": ("k_c", "k_phi", "n", "phi", "R", "sigma_F", "sigma_T", "sigma_z"),
}


def table2_prior(case: str) -> JointPrior:
    """Prior of the paper's Table 2 for case "1" (with J) or "2" (with R; also "2a"/"2b").

    Note the friction angle ``phi`` is in degrees, as in Table 2.
    """
    key = str(case).strip()
    if key in ("2a", "2b"):
        key = "2"
    if key not in _CASES:
        raise ValueError(f"'case' must be '1' or '2' (or '2a'/'2b'), got {case!r}")
    names = _CASES[key]
    return JointPrior({n: _TABLE2[n][0] for n in names}, {n: _TABLE2[n][1] for n in names})
