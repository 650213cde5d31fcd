"""Morris elementary-effects screening (paper section 4.4, Figure 4; Saltelli et al. 2000).

Design: r one-at-a-time trajectories of d + 1 points on a p-level grid of the unit cube
{0, 1/(p-1), ..., 1} with step delta = p / (2 (p - 1)) (Morris 1991), mapped to the parameter box
linearly, or log-linearly for parameters flagged in ``log_scale`` (moduli spanning decades).

Scaling of the elementary effects: EE_i = [y(u + delta e_i) - y(u)] / delta with u in the unit
cube, i.e. per unit of the *normalised* parameter (as SALib). For y = sum_i a_i x_i on a box,
EE_i = a_i (upper_i - lower_i): mu*_i = |a_i| (upper_i - lower_i) and sigma_i = 0.

Indices of Figure 4 (per response): linear index_i = mu*_i / sum_j mu*_j and non-linear
index_i = sigma_i / sum_j sigma_j. mu* measures the overall (mostly linear/additive) influence,
sigma the non-linear and interaction part; normalising by the sum over parameters makes both
comparable across responses with different units (F in N, T in N m, z in m).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.inference import portable
from scm_core.inference.priors import JointPrior

__all__ = [
    "MorrisDesign",
    "MorrisResult",
    "design_from_points",
    "morris",
    "morris_analyze",
    "morris_design",
]

MapFn = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]


@dataclass(frozen=True, eq=False)
class MorrisDesign:
    """A Morris design: points (r (d+1), d) in parameter units plus what the analysis needs.

    unit_points: same points in the unit cube. factor (r, d): index of the parameter changed at
    step s of trajectory t. step (r, d): signed unit-cube change of that parameter (+-delta).
    """

    points: NDArray[np.float64]
    unit_points: NDArray[np.float64]
    factor: NDArray[np.int64]
    step: NDArray[np.float64]
    bounds: NDArray[np.float64]
    levels: int
    delta: float
    log_scale: NDArray[np.bool_]
    names: tuple[str, ...]

    @property
    def r(self) -> int:
        return int(self.factor.shape[0])

    @property
    def dim(self) -> int:
        return int(self.factor.shape[1])


@dataclass(frozen=True, eq=False)
class MorrisResult:
    """Morris statistics, arrays of shape (d, k) (k responses; k = 1 for scalar outputs).

    mu: mean EE; mu_star: mean |EE|; sigma: standard deviation of EE (ddof = 1, as SALib);
    linear_index = mu_star / sum over parameters; nonlinear_index = sigma / sum over parameters
    (0 where all sigma of a response vanish). ee (r, d, k): the elementary effects.
    """

    names: tuple[str, ...]
    mu: NDArray[np.float64]
    mu_star: NDArray[np.float64]
    sigma: NDArray[np.float64]
    linear_index: NDArray[np.float64]
    nonlinear_index: NDArray[np.float64]
    ee: NDArray[np.float64]

    def ranking(self, response: int = 0) -> list[str]:
        """Parameter names by decreasing mu* for one response."""
        order = np.argsort(-self.mu_star[:, response], kind="stable")
        return [self.names[i] for i in order]


def _resolve_bounds(
    bounds: ArrayLike | JointPrior, names: Sequence[str] | None
) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    if isinstance(bounds, JointPrior):
        b = bounds.bounds
        names = names or bounds.names
    else:
        b = np.asarray(bounds, dtype=float)
    if b.ndim != 2 or b.shape[1] != 2:
        raise ValueError(f"'bounds' must have shape (d, 2), got {b.shape}")
    if not np.all(np.isfinite(b)) or not np.all(b[:, 0] < b[:, 1]):
        raise ValueError("'bounds' must be finite with lower < upper in every row")
    d = b.shape[0]
    names = tuple(names) if names is not None else tuple(f"x{i}" for i in range(d))
    if len(names) != d:
        raise ValueError(f"'names' has {len(names)} entries for {d} parameters")
    return b, names


def _to_box(
    U: NDArray[np.float64], bounds: NDArray[np.float64], log_scale: NDArray[np.bool_]
) -> NDArray[np.float64]:
    lo, hi = bounds[:, 0], bounds[:, 1]
    X = lo + U * (hi - lo)
    if log_scale.any():
        llo, lhi = portable.log(lo[log_scale]), portable.log(hi[log_scale])
        X[:, log_scale] = portable.exp(llo + U[:, log_scale] * (lhi - llo))
    return X


def _log_flags(log_scale: Sequence[bool] | None, bounds: NDArray[np.float64]) -> NDArray[np.bool_]:
    d = bounds.shape[0]
    flags = np.zeros(d, bool) if log_scale is None else np.asarray(log_scale, dtype=bool)
    if flags.shape != (d,):
        raise ValueError(f"'log_scale' must have {d} entries")
    if np.any(bounds[flags, 0] <= 0):
        raise ValueError("'log_scale' parameters need lower bound > 0")
    return flags


def morris_design(
    bounds: ArrayLike | JointPrior,
    r: int = 20,
    levels: int = 4,
    seed: int = 0,
    names: Sequence[str] | None = None,
    log_scale: Sequence[bool] | None = None,
) -> tuple[NDArray[np.float64], MorrisDesign]:
    """r random trajectories on a ``levels``-level grid (Morris 1991; Saltelli et al. 2000, 4.4).

    Each trajectory starts at a random grid point u* with u*_i in {0, ..., 1 - delta} and changes
    the parameters one at a time, in random order, by +-delta (direction random), staying in the
    unit cube. ``bounds``: (d, 2) array or a JointPrior (its bounds; pass explicit bounds for
    priors with very wide ranges). Returns (points (r (d+1), d), design).
    """
    b, names = _resolve_bounds(bounds, names)
    flags = _log_flags(log_scale, b)
    if levels < 2 or levels % 2:
        raise ValueError(f"'levels' must be an even integer >= 2, got {levels!r}")
    if r < 2:
        raise ValueError(f"'r' must be >= 2, got {r!r}")
    d = b.shape[0]
    delta = levels / (2.0 * (levels - 1))
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed)))
    n_start = levels // 2  # grid values 0 .. 1 - delta
    U = np.empty((r, d + 1, d))
    factor = np.empty((r, d), dtype=np.int64)
    step = np.empty((r, d))
    for t in range(r):
        base = rng.integers(0, n_start, size=d) / (levels - 1)
        up = rng.random(d) < 0.5
        order = rng.permutation(d)
        u = np.where(up, base, base + delta)
        U[t, 0] = u
        for s, i in enumerate(order):
            u = u.copy()
            u[i] = base[i] + delta if up[i] else base[i]
            U[t, s + 1] = u
            factor[t, s] = i
            step[t, s] = delta if up[i] else -delta
    unit = U.reshape(r * (d + 1), d)
    design = MorrisDesign(
        points=_to_box(unit, b, flags),
        unit_points=unit,
        factor=factor,
        step=step,
        bounds=b,
        levels=int(levels),
        delta=float(delta),
        log_scale=flags,
        names=names,
    )
    return design.points, design


def design_from_points(
    points: ArrayLike,
    bounds: ArrayLike | JointPrior,
    levels: int = 4,
    names: Sequence[str] | None = None,
    log_scale: Sequence[bool] | None = None,
) -> MorrisDesign:
    """Rebuild a :class:`MorrisDesign` from trajectory points made elsewhere (e.g. SALib).

    Consecutive points of each trajectory must differ in exactly one parameter.
    """
    b, names = _resolve_bounds(bounds, names)
    flags = _log_flags(log_scale, b)
    X = np.asarray(points, dtype=float)
    d = b.shape[0]
    if X.ndim != 2 or X.shape[1] != d or X.shape[0] % (d + 1):
        raise ValueError(f"'points' must have shape (r * {d + 1}, {d}), got {X.shape}")
    lo, hi = b[:, 0].copy(), b[:, 1].copy()
    V = X.copy()
    V[:, flags] = portable.log(V[:, flags])
    lo[flags], hi[flags] = portable.log(lo[flags]), portable.log(hi[flags])
    unit = (V - lo) / (hi - lo)
    r = X.shape[0] // (d + 1)
    T = unit.reshape(r, d + 1, d)
    diff = np.diff(T, axis=1)
    changed = np.abs(diff) > 1e-9
    if not np.all(changed.sum(axis=2) == 1):
        raise ValueError("each step of a trajectory must change exactly one parameter")
    factor = np.argmax(changed, axis=2).astype(np.int64)
    step = np.take_along_axis(diff, factor[:, :, None], axis=2)[:, :, 0]
    return MorrisDesign(
        points=X,
        unit_points=unit,
        factor=factor,
        step=step,
        bounds=b,
        levels=int(levels),
        delta=levels / (2.0 * (levels - 1)),
        log_scale=flags,
        names=names,
    )


def morris_analyze(design: MorrisDesign, Y: ArrayLike) -> MorrisResult:
    """Elementary effects and indices from outputs Y (N,) or (N, k), N = r (d + 1).

    EE for parameter i in trajectory t = (y_after - y_before) / step (unit-cube scaling). Each
    parameter changes by exactly +-delta once per trajectory.
    """
    Y = np.asarray(Y, dtype=float)
    Y2 = Y.reshape(-1, 1) if Y.ndim == 1 else Y
    r, d = design.r, design.dim
    if Y2.shape[0] != r * (d + 1):
        raise ValueError(f"'Y' has {Y2.shape[0]} rows, design has {r * (d + 1)} points")
    k = Y2.shape[1]
    T = Y2.reshape(r, d + 1, k)
    dy = np.diff(T, axis=1) / design.step[:, :, None]  # (r, d steps, k)
    ee = np.empty((r, d, k))
    rows = np.arange(r)[:, None]
    ee[rows, design.factor] = dy
    mu = ee.mean(axis=0)
    mu_star = np.abs(ee).mean(axis=0)
    sigma = ee.std(axis=0, ddof=1)
    sum_mu = mu_star.sum(axis=0, keepdims=True)
    sum_sigma = sigma.sum(axis=0, keepdims=True)
    linear = np.divide(mu_star, sum_mu, out=np.zeros_like(mu_star), where=sum_mu > 0)
    tiny = sum_sigma <= 1e-12 * np.maximum(sum_mu, np.finfo(float).tiny)
    nonlinear = np.divide(sigma, sum_sigma, out=np.zeros_like(sigma), where=~tiny)
    return MorrisResult(
        names=design.names,
        mu=mu,
        mu_star=mu_star,
        sigma=sigma,
        linear_index=linear,
        nonlinear_index=nonlinear,
        ee=ee,
    )


def _apply(func_batch: Callable[[NDArray[np.float64]], ArrayLike], X: NDArray[np.float64]):
    return np.asarray(func_batch(X), dtype=float)


def morris(
    func_batch: Callable[[NDArray[np.float64]], ArrayLike],
    bounds: ArrayLike | JointPrior,
    r: int = 20,
    levels: int = 4,
    seed: int = 0,
    map: MapFn = map,
    batch_size: int | None = None,
    names: Sequence[str] | None = None,
    log_scale: Sequence[bool] | None = None,
) -> MorrisResult:
    """Design, evaluate and analyse a Morris screening.

    ``func_batch(X)`` maps points (m, d) to outputs (m,) or (m, k); batches of ``batch_size``
    points (None: one batch) are evaluated with ``map`` as in :func:`.tmcmc.run_tmcmc`.
    """
    points, design = morris_design(bounds, r, levels, seed, names, log_scale)
    n = points.shape[0]
    size = n if batch_size is None else int(batch_size)
    if size < 1:
        raise ValueError(f"'batch_size' must be >= 1 or None, got {batch_size!r}")
    chunks = [points[i : i + size] for i in range(0, n, size)]
    outs = list(map(partial(_apply, func_batch), chunks))
    Y = np.concatenate([o.reshape(o.shape[0], -1) for o in outs], axis=0)
    return morris_analyze(design, Y[:, 0] if Y.shape[1] == 1 else Y)
