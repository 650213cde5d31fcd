"""Posterior summaries and densities from TMCMC samples (paper section 5, Figures 5-9).

All functions take plain arrays: samples (n, d) in the prior's parameter order, equally weighted
(TMCMC's final stage is an equally weighted sample of the posterior).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "QUANTILES",
    "PosteriorSummary",
    "credible_interval",
    "kde_1d",
    "kde_2d",
    "map_sample",
    "pool_samples",
    "summarize",
    "summarize_result",
]

QUANTILES = (0.025, 0.25, 0.5, 0.75, 0.975)


@dataclass(frozen=True, eq=False)
class PosteriorSummary:
    """Per-parameter mean, sd (ddof = 1), quantiles (len(QUANTILES), d), correlation (d, d),
    and the MAP sample (argmax of log prior + log likelihood among the samples) if available."""

    names: tuple[str, ...]
    mean: NDArray[np.float64]
    sd: NDArray[np.float64]
    quantile_levels: tuple[float, ...]
    quantiles: NDArray[np.float64]
    correlation: NDArray[np.float64]
    map_sample: NDArray[np.float64] | None
    map_log_posterior: float | None

    def as_rows(self) -> list[dict[str, float | str]]:
        """One dict per parameter (name, mean, sd, q2.5, ..., map) for tables."""
        rows = []
        for j, name in enumerate(self.names):
            row: dict[str, float | str] = {"name": name, "mean": self.mean[j], "sd": self.sd[j]}
            for q, v in zip(self.quantile_levels, self.quantiles[:, j], strict=True):
                row[f"q{100 * q:g}"] = float(v)
            if self.map_sample is not None:
                row["map"] = float(self.map_sample[j])
            rows.append(row)
        return rows


def _as_2d(samples: ArrayLike) -> NDArray[np.float64]:
    X = np.asarray(samples, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2 or X.shape[0] < 2:
        raise ValueError(f"'samples' must have shape (n >= 2, d), got {X.shape}")
    return X


def map_sample(
    samples: ArrayLike, log_prior: ArrayLike, log_likelihood: ArrayLike
) -> tuple[NDArray[np.float64], float]:
    """Sample with the largest unnormalised log posterior log prior + log L, and that value."""
    X = _as_2d(samples)
    lp = np.asarray(log_prior, dtype=float) + np.asarray(log_likelihood, dtype=float)
    lp = np.where(np.isnan(lp), -np.inf, lp)
    i = int(np.argmax(lp))
    return X[i].copy(), float(lp[i])


def summarize(
    samples: ArrayLike,
    names: Sequence[str] | None = None,
    log_prior: ArrayLike | None = None,
    log_likelihood: ArrayLike | None = None,
    quantiles: Sequence[float] = QUANTILES,
) -> PosteriorSummary:
    """Mean, sd, quantiles, correlation matrix and (given log prior and log L) the MAP sample."""
    X = _as_2d(samples)
    d = X.shape[1]
    names = tuple(names) if names is not None else tuple(f"x{i}" for i in range(d))
    if len(names) != d:
        raise ValueError(f"'names' has {len(names)} entries for {d} parameters")
    sd = X.std(axis=0, ddof=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.corrcoef(X, rowvar=False).reshape(d, d)
    best, best_lp = (None, None)
    if log_prior is not None and log_likelihood is not None:
        best, best_lp = map_sample(X, log_prior, log_likelihood)
    return PosteriorSummary(
        names=names,
        mean=X.mean(axis=0),
        sd=sd,
        quantile_levels=tuple(float(q) for q in quantiles),
        quantiles=np.quantile(X, quantiles, axis=0),
        correlation=corr,
        map_sample=best,
        map_log_posterior=best_lp,
    )


def summarize_result(result: object) -> PosteriorSummary:
    """:func:`summarize` of a TMCMC result's final stage (``samples``, ``names``, ``log_prior``,
    ``log_likelihood`` attributes), MAP included."""
    return summarize(
        result.samples,  # type: ignore[attr-defined]
        result.names,  # type: ignore[attr-defined]
        result.log_prior,  # type: ignore[attr-defined]
        result.log_likelihood,  # type: ignore[attr-defined]
    )


def credible_interval(samples: ArrayLike, level: float = 0.95) -> NDArray[np.float64]:
    """Equal-tailed credible interval: (2,) for 1-D samples, (d, 2) for (n, d)."""
    if not 0 < level < 1:
        raise ValueError(f"'level' must be in (0, 1), got {level!r}")
    X = np.asarray(samples, dtype=float)
    a = (1.0 - level) / 2.0
    q = np.quantile(X, [a, 1.0 - a], axis=0)
    return q if X.ndim == 1 else q.T


def kde_1d(
    samples: ArrayLike,
    grid: ArrayLike | None = None,
    n_grid: int = 200,
    bounds: tuple[float, float] | None = None,
    bw_method: str | float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Univariate Gaussian KDE (scipy.stats.gaussian_kde) on a grid, as in Figure 5.

    With ``bounds`` = (lower, upper) (e.g. the prior support), the density is reflected at the
    bounds so that mass piled against a bound is not smeared outside it, and is 0 outside.
    Returns (grid, density); the density integrates to ~1 over the grid's range.
    """
    from scipy import stats  # on first use (a second to import)

    x = np.asarray(samples, dtype=float).ravel()
    kde = stats.gaussian_kde(x, bw_method=bw_method)
    if grid is None:
        if bounds is not None:
            lo, hi = bounds
        else:
            pad = 3.0 * float(np.sqrt(kde.covariance[0, 0]))
            lo, hi = x.min() - pad, x.max() + pad
        grid = np.linspace(lo, hi, n_grid)
    g = np.asarray(grid, dtype=float)
    dens = kde(g)
    if bounds is not None:
        lo, hi = bounds
        dens = dens + kde(2.0 * lo - g) + kde(2.0 * hi - g)
        dens = np.where((g >= lo) & (g <= hi), dens, 0.0)
    return g, dens


def kde_2d(
    x: ArrayLike,
    y: ArrayLike,
    n_grid: int = 100,
    limits: tuple[float, float, float, float] | None = None,
    bw_method: str | float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Bivariate Gaussian KDE on a grid for contour plots (Figures 6-9).

    ``limits`` = (x_min, x_max, y_min, y_max), default the data range padded by three kernel
    standard deviations, where one sample's kernel has fallen to exp(-4.5) = 1 % of its peak:
    contours down to a few per cent of the density's maximum close inside the grid.
    Returns (gx (n_grid,), gy (n_grid,), density (n_grid, n_grid) indexed [iy, ix]).
    """
    xv = np.asarray(x, dtype=float).ravel()
    yv = np.asarray(y, dtype=float).ravel()
    from scipy import stats

    kde = stats.gaussian_kde(np.vstack([xv, yv]), bw_method=bw_method)
    if limits is None:
        px, py = 3.0 * np.sqrt(np.diag(kde.covariance))
        limits = (xv.min() - px, xv.max() + px, yv.min() - py, yv.max() + py)
    gx = np.linspace(limits[0], limits[1], n_grid)
    gy = np.linspace(limits[2], limits[3], n_grid)
    XX, YY = np.meshgrid(gx, gy)
    dens = kde(np.vstack([XX.ravel(), YY.ravel()])).reshape(n_grid, n_grid)
    return gx, gy, dens


def pool_samples(
    runs: Sequence[ArrayLike], n_per_run: int | None = None, seed: int = 0
) -> NDArray[np.float64]:
    """Pool the final samples of several runs into one set (Figure 9), equal weight per run.

    Each run is one equally weighted posterior sample; giving each run the same number of rows
    gives each run weight 1/len(runs), whatever its size. Runs larger than ``n_per_run``
    (default: the smallest run's size) are subsampled without replacement (seeded); smaller runs
    are an error. Returns (len(runs) * n_per_run, d), runs in order.
    """
    arrays = [_as_2d(r) for r in runs]
    if not arrays:
        raise ValueError("'runs' must not be empty")
    d = arrays[0].shape[1]
    if any(a.shape[1] != d for a in arrays):
        raise ValueError("all runs must have the same number of parameters")
    m = min(a.shape[0] for a in arrays) if n_per_run is None else int(n_per_run)
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed)))
    out = []
    for i, a in enumerate(arrays):
        if a.shape[0] < m:
            raise ValueError(f"run {i} has {a.shape[0]} samples, fewer than n_per_run={m}")
        out.append(a if a.shape[0] == m else a[np.sort(rng.choice(a.shape[0], m, replace=False))])
    return np.concatenate(out, axis=0)
