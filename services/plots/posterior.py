"""Posterior figures like the paper's Figures 5-8: prior vs posterior histograms and bivariate
kernel-density contours of selected parameter pairs."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.posterior import kde_1d, kde_2d

from .chart import Axis, Chart, Panel, bars, contours, line, marker, points, vline
from .choices import default_pairs
from .figures import save

if TYPE_CHECKING:
    from matplotlib.figure import Figure

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


#: SI units drawn in a handier one, so that no axis needs an exponent beside its unit (the
#: pair plot's J axis read "1e-3" beside "[m/s]"): values in mm/s and mm
_SHOWN_AS = {"m/s": ("mm/s", 1e3), "m": ("mm", 1e3)}


def _si_unit(name: str, units: Mapping[str, str] | None) -> str | None:
    if units and name in units:
        return units[name]
    known = _LABELS.get(name, "")
    return known[known.index("[") + 1 : -1] if known.endswith("]") else None


def shown_scale(name: str, units: Mapping[str, str] | None = None) -> float:
    """The factor from a parameter's SI value to the value drawn (1e3 for m/s and m)."""
    return _SHOWN_AS.get(_si_unit(name, units) or "", ("", 1.0))[1]


def label(name: str, units: Mapping[str, str] | None = None) -> str:
    si = _si_unit(name, units)
    if si in _SHOWN_AS:
        return f"{name} [{_SHOWN_AS[si][0]}]"
    if units and name in units and units[name] not in ("", "-"):
        return f"{name} [{units[name]}]"
    return _LABELS.get(name, name)


def _log(name: str, log_params: Collection[str]) -> bool:
    return name in log_params


def _tx(name: str, x, log_params: Collection[str], units: Mapping[str, str] | None = None):
    """Values on the plotting scale: log10 for parameters with a log-uniform prior, else in
    the unit drawn (:func:`shown_scale`)."""
    if not _log(name, log_params):
        return np.asarray(x, dtype=float) * shown_scale(name, units)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log10(np.asarray(x, dtype=float))


def _from_plot_scale(log: bool) -> Any:
    """The inverse of :func:`_tx` for one parameter: 10**v on a log10 scale, else v."""
    return (lambda v: 10.0 ** np.asarray(v)) if log else np.asarray


def _density_grid(d: int) -> tuple[Figure, NDArray[Any]]:
    """A figure with one density panel per parameter, four to a row."""
    from matplotlib.figure import Figure

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


def _density(v: NDArray[np.float64], edges: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bar heights of ``v`` binned at ``edges`` (on the binning scale) as a density per unit
    of that scale (per decade for log10 bins), whatever scale the bars are drawn on."""
    v = v[np.isfinite(v)]
    counts, _ = np.histogram(v, bins=edges)
    return counts / (max(v.size, 1) * (edges[1] - edges[0]))


def _density_panel(name: str, units: Mapping[str, str] | None, log: bool, first: bool) -> Panel:
    """A density panel: a log axis (density per decade) for a log-scale parameter."""
    return Panel(
        Axis(label(name, units), scale="log" if log else "linear"),
        Axis("density per decade" if log else "density", lo=0.0),
        legend="best" if first else None,
    )


def _grid_chart(title: str, panels: list[Panel | None]) -> Chart:
    """Density panels, four to a row."""
    ncols = min(4, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    return Chart(title, panels, columns=ncols, size=(3.4 * ncols, 2.8 * nrows + 0.4))


def prior_posterior_chart(
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
) -> Chart:
    """Histograms (densities) of prior and posterior samples per parameter (Figure 5);
    ``labels`` names the two (an update: the earlier and the updated posterior);
    parameters in ``log_params`` (log-uniform priors, e.g. the moduli) are binned in log10 and
    drawn on a log axis, their density per decade."""
    panels: list[Panel | None] = []
    for j, name in enumerate(names):
        log = _log(name, log_params)
        back = _from_plot_scale(log)
        pr = _tx(name, prior_samples[:, j], log_params, units)
        po = _tx(name, posterior_samples[:, j], log_params, units)
        if bounds is not None:
            lo, hi = _tx(name, bounds[j], log_params, units)
        else:
            lo, hi = min(np.nanmin(pr), np.nanmin(po)), max(np.nanmax(pr), np.nanmax(po))
        if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
            lo, hi = float(np.nanmin(po)) - 0.5, float(np.nanmax(po)) + 0.5
        panel = _density_panel(name, units, log, first=j == 0)
        # densities on the binning scale (per unit, or per decade), drawn at the values
        edges = np.linspace(lo, hi, 41)
        panel.add(bars(back(edges), _density(pr, edges), "light", label=labels[0]))
        p_lo, p_hi = float(np.nanmin(po)), float(np.nanmax(po))
        if p_hi > p_lo:
            fine = np.linspace(p_lo, p_hi, 31)
            panel.add(bars(back(fine), _density(po, fine), "blue", opacity=0.75, label=labels[1]))
        else:
            panel.add(vline(float(back(p_lo)), "blue", width=2.0, label=labels[1]))
        if map_sample is not None:
            at = float(back(_tx(name, map_sample[j], log_params, units)))
            panel.add(vline(at, "red", label="MAP"))
        if reference and name in reference:
            at = float(back(_tx(name, reference[name], log_params, units)))
            panel.add(vline(at, "black", width=1.0, dash="dotted", label="bevameter"))
        panels.append(panel)
    _legend_where_all_are(panels)
    return _grid_chart(title or "Prior and posterior densities", panels)


def _labels(panel: Panel) -> list[str]:
    return [la["label"] for la in panel.layers if la.get("label")]


def _legend_where_all_are(panels: list[Panel]) -> None:
    """One legend, on the first panel that shows every labelled kind of layer of the chart
    (the bevameter's dotted line is drawn only where a value is known: a legend on the first
    panel left it out), else on the one that shows the most."""
    everything = {lab for p in panels for lab in _labels(p)}
    best = max(panels, key=lambda p: (set(_labels(p)) >= everything, len(set(_labels(p)))))
    for p in panels:
        p.legend = "best" if p is best else None


def plot_prior_posterior(
    names: Sequence[str],
    prior_samples: NDArray[np.float64],
    posterior_samples: NDArray[np.float64],
    path: str | Path,
    **options: Any,
) -> Path:
    """:func:`prior_posterior_chart` drawn to ``path`` (PNG, SVG, PDF by its suffix)."""
    from .mpl import draw

    chart = prior_posterior_chart(names, prior_samples, posterior_samples, **options)
    return save(draw(chart), path)


def _contour_levels(
    x: NDArray[np.float64], y: NDArray[np.float64], n_grid: int, n_levels: int
) -> list[tuple[float, list[tuple[NDArray[np.float64], NDArray[np.float64]]]]]:
    """Kernel-density contours of (x, y) at ``n_levels`` levels from 5 to 95 % of the density's
    maximum, closed (:func:`kde_2d` pads three kernel sds): [(level, [(px, py), ...]), ...];
    none where the sample is degenerate (a line, a few distinct points)."""
    distinct = np.unique(np.column_stack([x, y]), axis=0).shape[0]
    if not (np.ptp(x) > 0 and np.ptp(y) > 0 and distinct > 3):
        return []
    try:
        gx, gy, dens = kde_2d(x, y, n_grid=n_grid)
    except (np.linalg.LinAlgError, ValueError):
        return []
    import contourpy

    gen = contourpy.contour_generator(gx, gy, dens, line_type="Separate")
    out = []
    for level in np.linspace(0.05, 0.95, n_levels) * float(dens.max()):
        out.append((float(level), [(p[:, 0], p[:, 1]) for p in gen.lines(level)]))
    return out


def _scaled_paths(
    levels: list[tuple[float, list[tuple[NDArray[np.float64], NDArray[np.float64]]]]],
    bx: Any,
    by: Any,
) -> list[tuple[float, list[tuple[NDArray[np.float64], NDArray[np.float64]]]]]:
    """Contour paths from the estimation scale (log10) back to the values drawn."""
    return [(v, [(bx(px), by(py)) for px, py in paths]) for v, paths in levels]


def pairs_chart(
    names: Sequence[str],
    samples: NDArray[np.float64],
    pairs: Sequence[tuple[str, str]] | None = None,
    units: Mapping[str, str] | None = None,
    reference: Mapping[str, float] | None = None,
    k_star_line: tuple[float, float] | None = None,
    title: str | None = None,
    log_params: Collection[str] = (),
    max_points: int = 4000,
) -> Chart | None:
    """Bivariate kernel-density contours of posterior pairs (Figures 6-8); parameters in
    ``log_params`` are drawn on log axes (their densities estimated in log10).

    ``k_star_line`` = (k*, b_eff) draws the dashed line k_c / b_eff + k_phi = k* on the k_c-k_phi
    panel (the paper's bevameter k* at the simulations' mean b_eff); ``reference`` marks
    bevameter means. At most ``max_points`` samples (an even thinning of the equally weighted
    sample) are drawn as dots and enter the kernel density. None if no pair.
    """
    pairs = list(pairs) if pairs is not None else default_pairs(names)
    if not pairs:
        return None
    index = {n: j for j, n in enumerate(names)}
    panels: list[Panel | None] = []
    for a, b in pairs:
        # estimated on the plotting scale (log10 for log-uniform priors), drawn at the values
        log_a, log_b = _log(a, log_params), _log(b, log_params)
        bx, by = _from_plot_scale(log_a), _from_plot_scale(log_b)
        x = _tx(a, samples[:, index[a]], log_params, units)
        y = _tx(b, samples[:, index[b]], log_params, units)
        step = max(1, math.ceil(x.size / max_points))
        x, y = x[::step], y[::step]
        panel = Panel(
            Axis(label(a, units), scale="log" if log_a else "linear"),
            Axis(label(b, units), scale="log" if log_b else "linear"),
        ).add(points(bx(x), by(y), label="samples"))
        levels = _contour_levels(x, y, n_grid=80, n_levels=8)
        if levels:
            panel.add(contours(_scaled_paths(levels, bx, by), label="density"))
        if k_star_line is not None and (a, b) == ("k_c", "k_phi"):
            k_star, b_eff = k_star_line
            k_c = bx(np.linspace(float(np.nanmin(x)), float(np.nanmax(x)), 200))
            with np.errstate(invalid="ignore"):
                k_phi = k_star - k_c / b_eff
            if log_b:
                k_phi = np.where(k_phi > 0, k_phi, np.nan)
            panel.add(line(k_c, k_phi, "grey", dash="dashed", label=f"k* = {k_star:.3g}"))
        ref = {**(reference or {})}
        if "k_star" in ref and (a, b) == ("k_c", "k_phi"):
            ref.setdefault("k_c", 0.0)
            ref.setdefault("k_phi", ref["k_star"])
        if a in ref and b in ref:
            ra, rb = (float(f(_tx(n, ref[n], log_params, units))) for n, f in ((a, bx), (b, by)))
            panel.add(marker(ra, rb, label="bevameter"))
        panels.append(panel)
    return Chart(
        title or "Bivariate posterior densities",
        panels,
        columns=len(panels),
        size=(max(4.6 * len(panels), 6.4), 4.4),
    )


def plot_pairs(
    names: Sequence[str], samples: NDArray[np.float64], path: str | Path, **options: Any
) -> Path | None:
    """:func:`pairs_chart` drawn to ``path``; None (nothing written) if no pair."""
    from .mpl import draw

    chart = pairs_chart(names, samples, **options)
    return None if chart is None else save(draw(chart), path)


def pair_matrix_chart(
    names: Sequence[str],
    samples: NDArray[np.float64],
    chosen: Sequence[str],
    units: Mapping[str, str] | None = None,
    reference: Mapping[str, float] | None = None,
    log_params: Collection[str] = (),
    title: str | None = None,
    max_points: int = 2000,
) -> Chart:
    """A pair matrix of the ``chosen`` parameters (a corner plot): on the diagonal each one's
    marginal (histogram and kernel density), below it each pair's samples and kernel-density
    contours (5-95 % of the maximum, closed: :func:`kde_2d`). Parameters in ``log_params`` are
    estimated and drawn in log10 (axes labelled log10). ``reference`` marks bevameter values."""
    index = {n: j for j, n in enumerate(names)}
    d = len(chosen)
    step = max(1, math.ceil(samples.shape[0] / max_points))
    cols = {n: _tx(n, samples[::step, index[n]], log_params, units) for n in chosen}

    def name_of(n: str) -> str:
        return f"log10 {label(n, units)}" if _log(n, log_params) else label(n, units)

    ref = {
        n: float(_tx(n, np.array([v]), log_params, units)[0])
        for n, v in (reference or {}).items()
        if n in cols
    }
    panels: list[Panel | None] = []
    for i, a in enumerate(chosen):
        for k, b in enumerate(chosen):
            if k > i:
                panels.append(None)
                continue
            x, y = cols[b], cols[a]
            x_axis = Axis(name_of(b) if i == d - 1 else "", tick_labels=i == d - 1)
            if k == i:
                ok = x[np.isfinite(x)]
                panel = Panel(x_axis, Axis("", lo=0.0, tick_labels=False), legend=None)
                if ok.size and np.ptp(ok) > 0:
                    edges = np.linspace(ok.min(), ok.max(), 31)
                    panel.add(bars(edges, _density(ok, edges), "blue", opacity=0.35))
                if ok.size > 3 and np.ptp(ok) > 0:
                    g, dens = kde_1d(ok)
                    panel.add(line(g, dens, "blue"))
                if b in ref:
                    panel.add(vline(ref[b], "black", width=1.0, dash="dashed"))
            else:
                y_axis = Axis(name_of(a) if k == 0 else "", tick_labels=k == 0)
                panel = Panel(x_axis, y_axis, legend=None).add(points(x, y, size=1.2, opacity=0.35))
                levels = _contour_levels(x, y, n_grid=60, n_levels=6)
                if levels:
                    panel.add(contours(levels, width=0.9))
                if a in ref and b in ref:
                    panel.add(marker(ref[b], ref[a], size=10.0))
            panels.append(panel)
    return Chart(
        title or "Pair matrix of the posterior",
        panels,
        columns=d,
        size=(1.9 * d + 1.0, 1.9 * d + 0.6),
        reflow="none",  # a corner plot: its rows and columns are the same parameters
    )


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
        every = [_tx(name, x[:, j], log_params, units) for x in studies.values()]
        if pooled is not None:
            every.append(_tx(name, pooled[:, j], log_params, units))
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
