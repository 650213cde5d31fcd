"""Posterior figures like the paper's Figures 5-8: prior vs posterior histograms and bivariate
kernel-density contours of selected parameter pairs."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from scm_core.inference.posterior import kde_1d, kde_2d

from .choices import default_pairs
from .figures import save

_LABELS = {
    "k_c": "k_c [N/m^(n+1)]",
    "k_phi": "k_phi [N/m^(n+2)]",
    "n": "n [-]",
    "phi": "phi [deg]",
    "J": "J [m/s]",
    "R": "R [m]",
    "c": "c [Pa]",
    "D_soil": "D_soil [N s/m^3]",
    "sigma_F": "sigma_F [N]",
    "sigma_T": "sigma_T [N m]",
    "sigma_z": "sigma_z [m]",
}


def label(name: str, units: Mapping[str, str] | None = None) -> str:
    if units and name in units and units[name] not in ("", "-"):
        return f"{name} [{units[name]}]"
    return _LABELS.get(name, name)


def _log(name: str, log_params: Collection[str]) -> bool:
    return name in log_params


def _tx(name: str, x, log_params: Collection[str]):
    """Values on the plotting scale: log10 for parameters with a log-uniform prior."""
    if not _log(name, log_params):
        return x
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log10(np.asarray(x, dtype=float))


def _from_plot_scale(log: bool) -> Any:
    """The inverse of :func:`_tx` for one parameter: 10**v on a log10 scale, else v."""
    return (lambda v: 10.0 ** np.asarray(v)) if log else np.asarray


def _density_grid(d: int) -> tuple[Figure, NDArray[Any]]:
    """A figure with one density panel per parameter, four to a row."""
    ncols = min(4, d)
    nrows = math.ceil(d / ncols)
    fig = Figure(figsize=(3.4 * ncols, 2.8 * nrows + 0.4), layout="constrained")
    return fig, np.atleast_1d(fig.subplots(nrows, ncols)).ravel()


def _density_axis(ax: Any, name: str, units: Mapping[str, str] | None, log: bool) -> None:
    """Labels and scale of a density panel: a log axis (density per decade) for a
    log-scale parameter, else scientific tick labels."""
    ax.set_xlabel(label(name, units))
    ax.set_ylabel("density per decade" if log else "density")
    if log:
        ax.set_xscale("log")
    else:
        ax.ticklabel_format(style="sci", scilimits=(-3, 4))
    ax.grid(alpha=0.3)


def _close_grid(axes: NDArray[Any], d: int) -> None:
    """Hide the panels beyond the ``d`` parameters; the legend on the first."""
    for ax in axes[d:]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)


def _per_unit(v: NDArray[np.float64], width: float) -> NDArray[np.float64]:
    """Histogram weights that make bar heights a density per unit of the binning scale
    (per decade for log10 bins), whatever scale the bars are drawn on."""
    return np.full(v.size, 1.0 / (v.size * width))


def prior_posterior_figure(
    names: Sequence[str],
    prior_samples: NDArray[np.float64],
    posterior_samples: NDArray[np.float64],
    bounds: NDArray[np.float64] | None = None,
    units: Mapping[str, str] | None = None,
    map_sample: NDArray[np.float64] | None = None,
    reference: Mapping[str, float] | None = None,
    title: str | None = None,
    log_params: Collection[str] = (),
    labels: tuple[str, str] = ("prior", "posterior"),
) -> Figure:
    """Histograms (densities) of prior and posterior samples per parameter (Figure 5);
    ``labels`` names the two (an update: the earlier and the updated posterior);
    parameters in ``log_params`` (log-uniform priors, e.g. the moduli) are binned in log10 and
    drawn on a log axis, their density per decade."""
    d = len(names)
    fig, axes = _density_grid(d)
    for j, name in enumerate(names):
        ax = axes[j]
        log = _log(name, log_params)
        back = _from_plot_scale(log)
        pr = _tx(name, prior_samples[:, j], log_params)
        po = _tx(name, posterior_samples[:, j], log_params)
        if bounds is not None:
            lo, hi = _tx(name, bounds[j], log_params)
        else:
            lo, hi = min(pr.min(), po.min()), max(pr.max(), po.max())
        if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
            lo, hi = float(np.min(po)) - 0.5, float(np.max(po)) + 0.5
        edges = np.linspace(lo, hi, 41)
        # densities on the binning scale (per unit, or per decade), drawn at the values
        ax.hist(
            back(pr),
            bins=back(edges),
            weights=_per_unit(pr, edges[1] - edges[0]),
            color="0.75",
            label=labels[0],
        )
        p_lo, p_hi = float(po.min()), float(po.max())
        if p_hi > p_lo:
            fine = np.linspace(p_lo, p_hi, 31)
            ax.hist(
                back(po),
                bins=back(fine),
                weights=_per_unit(po, fine[1] - fine[0]),
                color="tab:blue",
                alpha=0.75,
                label=labels[1],
            )
        else:
            ax.axvline(float(back(p_lo)), color="tab:blue", lw=2, label=labels[1])
        if map_sample is not None:
            ax.axvline(map_sample[j], color="tab:red", lw=1.2, label="MAP")
        if reference and name in reference:
            ax.axvline(reference[name], color="k", lw=1.0, ls=":", label="bevameter")
        _density_axis(ax, name, units, log)
    _close_grid(axes, d)
    fig.suptitle(title or "Prior and posterior densities")
    return fig


def plot_prior_posterior(
    names: Sequence[str],
    prior_samples: NDArray[np.float64],
    posterior_samples: NDArray[np.float64],
    path: str | Path,
    **options: Any,
) -> Path:
    """:func:`prior_posterior_figure` saved to ``path`` (PNG, SVG, PDF by its suffix)."""
    return save(prior_posterior_figure(names, prior_samples, posterior_samples, **options), path)


def pairs_figure(
    names: Sequence[str],
    samples: NDArray[np.float64],
    pairs: Sequence[tuple[str, str]] | None = None,
    units: Mapping[str, str] | None = None,
    reference: Mapping[str, float] | None = None,
    k_star_line: tuple[float, float] | None = None,
    title: str | None = None,
    log_params: Collection[str] = (),
    max_points: int = 4000,
) -> Figure | None:
    """Bivariate kernel-density contours of posterior pairs (Figures 6-8); parameters in
    ``log_params`` are drawn on log axes (their densities estimated in log10).

    ``k_star_line`` = (k*, b_eff) draws the dashed line k_c / b_eff + k_phi = k* on the k_c-k_phi
    panel (the paper's bevameter k* at the simulations' mean b_eff); ``reference`` marks
    bevameter means. At most
    ``max_points`` samples (an even thinning of the equally weighted sample) are drawn as
    dots, rasterised in vector formats, and enter the kernel density. None if no pair.
    """
    pairs = list(pairs) if pairs is not None else default_pairs(names)
    if not pairs:
        return None
    index = {n: j for j, n in enumerate(names)}
    fig = Figure(figsize=(max(4.6 * len(pairs), 6.4), 4.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(pairs)))
    for ax, (a, b) in zip(axes, pairs, strict=True):
        # estimated on the plotting scale (log10 for log-uniform priors), drawn at the values
        log_a, log_b = _log(a, log_params), _log(b, log_params)
        bx, by = _from_plot_scale(log_a), _from_plot_scale(log_b)
        x = _tx(a, samples[:, index[a]], log_params)
        y = _tx(b, samples[:, index[b]], log_params)
        step = max(1, math.ceil(x.size / max_points))
        ax.scatter(
            bx(x[::step]),
            by(y[::step]),
            s=5,
            color="0.3",
            alpha=0.45,
            lw=0,
            label="samples",
            rasterized=True,
        )
        distinct = np.unique(np.column_stack([x, y]), axis=0).shape[0]
        if np.ptp(x) > 0 and np.ptp(y) > 0 and distinct > 3:
            try:
                gx, gy, dens = kde_2d(x[::step], y[::step], n_grid=80)
                levels = np.linspace(0.05, 0.95, 8) * float(dens.max())
                ax.contour(bx(gx), by(gy), dens, levels=levels, cmap="viridis", linewidths=1.0)
            except (np.linalg.LinAlgError, ValueError):
                pass
        if log_a:
            ax.set_xscale("log")
        if log_b:
            ax.set_yscale("log")
        if k_star_line is not None and (a, b) == ("k_c", "k_phi"):
            k_star, b_eff = k_star_line
            lo, hi = ax.get_xlim()
            k_c = np.geomspace(lo, hi, 200) if log_a else np.linspace(lo, hi, 200)
            ylim = ax.get_ylim()
            with np.errstate(invalid="ignore"):
                k_phi = k_star - k_c / b_eff
            if log_b:
                k_phi = np.where(k_phi > 0, k_phi, np.nan)
            ax.plot(k_c, k_phi, "--", color="0.5", label=f"k* = {k_star:.3g}")
            ax.set_ylim(ylim)
        ref = {**(reference or {})}
        if "k_star" in ref and (a, b) == ("k_c", "k_phi"):
            ref.setdefault("k_c", 0.0)
            ref.setdefault("k_phi", ref["k_star"])
        if a in ref and b in ref:
            ax.plot(ref[a], ref[b], "k+", ms=12, mew=2, label="bevameter")
        ax.set_xlabel(label(a, units))
        ax.set_ylabel(label(b, units))
        if not log_a:
            ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
        if not log_b:
            ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or "Bivariate posterior densities")
    return fig


def pair_matrix_figure(
    names: Sequence[str],
    samples: NDArray[np.float64],
    chosen: Sequence[str],
    units: Mapping[str, str] | None = None,
    reference: Mapping[str, float] | None = None,
    log_params: Collection[str] = (),
    title: str | None = None,
    max_points: int = 2000,
) -> Figure:
    """A pair matrix of the ``chosen`` parameters (a corner plot): on the diagonal each one's
    marginal (histogram and kernel density), below it each pair's samples and kernel-density
    contours (5-95 % of the maximum, closed: :func:`kde_2d`). Parameters in ``log_params`` are
    estimated and drawn in log10 (axes labelled log10). ``reference`` marks bevameter values."""
    index = {n: j for j, n in enumerate(names)}
    d = len(chosen)
    fig = Figure(figsize=(1.9 * d + 1.0, 1.9 * d + 0.6), layout="constrained")
    axes = np.array(fig.subplots(d, d, squeeze=False))
    step = max(1, math.ceil(samples.shape[0] / max_points))
    cols = {n: _tx(n, samples[::step, index[n]], log_params) for n in chosen}

    def name_of(n: str) -> str:
        return f"log10 {label(n, units)}" if _log(n, log_params) else label(n, units)

    ref = {
        n: float(_tx(n, np.array([v]), log_params)[0])
        for n, v in (reference or {}).items()
        if n in cols
    }
    for i, a in enumerate(chosen):
        for k, b in enumerate(chosen):
            ax = axes[i, k]
            if k > i:
                ax.set_visible(False)
                continue
            x, y = cols[b], cols[a]
            if k == i:
                ok = x[np.isfinite(x)]
                ax.hist(ok, bins=30, density=True, color="tab:blue", alpha=0.35)
                if ok.size > 3 and np.ptp(ok) > 0:
                    g, dens = kde_1d(ok)
                    ax.plot(g, dens, color="tab:blue", lw=1.2)
                ax.set_yticks([])
                if b in ref:
                    ax.axvline(ref[b], color="k", ls="--", lw=1)
            else:
                ax.scatter(x, y, s=3, color="0.3", alpha=0.35, lw=0, rasterized=True)
                distinct = np.unique(np.column_stack([x, y]), axis=0).shape[0]
                if np.ptp(x) > 0 and np.ptp(y) > 0 and distinct > 3:
                    try:
                        gx, gy, dens = kde_2d(x, y, n_grid=60)
                        levels = np.linspace(0.05, 0.95, 6) * float(dens.max())
                        ax.contour(gx, gy, dens, levels=levels, cmap="viridis", linewidths=0.9)
                    except (np.linalg.LinAlgError, ValueError):
                        pass
                if a in ref and b in ref:
                    ax.plot(ref[b], ref[a], "k+", ms=10, mew=1.5)
            ax.tick_params(labelsize=7)
            if i == d - 1:
                ax.set_xlabel(name_of(b), fontsize=8)
            else:
                ax.set_xticklabels([])
            if k == 0 and i > 0:
                ax.set_ylabel(name_of(a), fontsize=8)
            elif k > 0 and k != i:
                ax.set_yticklabels([])
            ax.grid(alpha=0.25)
    fig.suptitle(title or "Pair matrix of the posterior")
    return fig


def plot_pairs(
    names: Sequence[str], samples: NDArray[np.float64], path: str | Path, **options: Any
) -> Path | None:
    """:func:`pairs_figure` saved to ``path``; None (nothing written) if no pair."""
    fig = pairs_figure(names, samples, **options)
    return None if fig is None else save(fig, path)


def compare_figure(
    names: Sequence[str],
    studies: Mapping[str, NDArray[np.float64]],
    pooled: NDArray[np.float64] | None = None,
    units: Mapping[str, str] | None = None,
    log_params: Collection[str] = (),
    title: str | None = None,
) -> Figure:
    """Posterior densities of shared parameters: each study's final stage as an outline and
    the pooled sample filled (the paper's Figure 9); ``studies`` maps a label to samples
    (n, len(names)) in the order of ``names``."""
    d = len(names)
    fig, axes = _density_grid(d)
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
    for j, name in enumerate(names):
        ax = axes[j]
        log = _log(name, log_params)
        back = _from_plot_scale(log)
        every = [_tx(name, x[:, j], log_params) for x in studies.values()]
        if pooled is not None:
            every.append(_tx(name, pooled[:, j], log_params))
        lo = min(float(np.nanmin(v)) for v in every)
        hi = max(float(np.nanmax(v)) for v in every)
        if not hi > lo:
            lo, hi = lo - 0.5, hi + 0.5
        edges = np.linspace(lo, hi, 41)
        width = edges[1] - edges[0]
        if pooled is not None:
            v = every[-1]
            ax.hist(
                back(v), bins=back(edges), weights=_per_unit(v, width), color="0.8", label="pooled"
            )
        for k, (lab, _) in enumerate(studies.items()):
            ax.hist(
                back(every[k]),
                bins=back(edges),
                weights=_per_unit(every[k], width),
                histtype="step",
                lw=1.4,
                color=colors[k % len(colors)],
                label=lab,
            )
        _density_axis(ax, name, units, log)
    _close_grid(axes, d)
    fig.suptitle(title or "Posterior densities of the compared studies and their pool")
    return fig
