"""Simulated vs measured SWT signals at a parameter sample (e.g. the MAP), like Figure 3."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from scm_core.signals import SWTDataset, TestConditions, lowpass
from scm_core.signals.responses import DEFAULT_KEYS, RESPONSE_KEYS, RESPONSES
from scm_core.simulator import ResolvedRig, SWTResult

from .angles import angle_grid, angle_of, by_slip_angle, steered
from .chart import (
    Axis,
    Chart,
    Panel,
    band,
    errorbars,
    hline,
    hspan,
    line,
    points,
    segment,
    text,
    vline,
    vspan,
)
from .figures import save

#: points per drawn curve at most: about two per pixel column of a panel (5.2 in at 100-120 dpi);
#: a 180 s lab log at 100 Hz drawn in full made one figure 254 KB of SVG (issue 45)
MAX_POINTS = 1200

_ROWS = tuple((r.key, r.column, r.label, r.scale, r.offset) for r in RESPONSES)
#: the x axis of a figure against slip
SLIP_LABEL = "slip (omega r - v) / max(v, omega r)  [-1 = locked]"
#: colours of the wheels of a study with several (a joint study of two wheels)
WHEEL_COLORS = ("blue", "orange", "green", "purple", "brown")
#: the two-sided 95 % quantile of a normal: a band of +- Z95 sigma holds 95 % of the tests
Z95 = 1.959964


def condition_label(c: TestConditions | ResolvedRig) -> str:
    """'slip 0.2, W 315 N' (the symmetric lab slip; 'locked' for a locked wheel)."""
    if c.slip_symmetric is None:
        kin = "slip ?"
    elif c.slip_symmetric <= -1.0:
        kin = "locked"
    else:
        kin = f"slip {c.slip_symmetric:.3g}"
    return f"{kin}, W {c.W:g} N"


def wheel_label(conditions: Mapping[str, Any]) -> str:
    """'R 125 mm, b 112 mm, 12 grousers of 9 mm' (or 'smooth'); '?' for what is unknown."""

    def mm(key: str) -> str:
        v = conditions.get(key)
        return "?" if v is None else f"{1000 * v:.4g}"

    n, h = conditions.get("n_grousers") or 0, conditions.get("grouser_height") or 0.0
    rim = f"{n} grousers of {1000 * h:.3g} mm" if n and h > 0 else "smooth"
    return f"R {mm('R')} mm, b {mm('b')} mm, {rim}"


def _filtered(t: np.ndarray, y: np.ndarray, cutoff_hz: float | None) -> np.ndarray:
    """The simulated signal through the lab logs' zero-phase low-pass, for a like-for-like
    look (unfiltered if too short or too coarsely sampled)."""
    if t.size < 30:
        return y
    rate = 1.0 / float(np.median(np.diff(t)))
    try:
        return lowpass(y, rate, cutoff_hz)
    except ValueError:
        return y


def decimated(
    t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS
) -> tuple[np.ndarray, np.ndarray]:
    """Min-max decimation of a curve to at most ``max_points`` points: the samples split into
    max_points / 2 consecutive bins, each drawn by its lowest and highest sample in time order,
    so the envelope a pixel column shows (grouser impacts, peaks) survives. Every point kept is
    a sample of the curve (a NaN only where its whole bin is NaN); curves of at most
    ``max_points`` samples are returned as they are."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = t.size
    if n <= max_points:
        return t, y
    bins = max(max_points // 2, 1)
    size = -(-n // bins)
    idx = np.arange(bins * size).reshape(bins, size)
    idx = np.minimum(idx, n - 1)  # the last bin repeats the last sample
    vals = np.where(np.isnan(y), np.inf, y)[idx]
    lo = idx[np.arange(bins), np.argmin(vals, axis=1)]
    vals = np.where(np.isnan(y), -np.inf, y)[idx]
    hi = idx[np.arange(bins), np.argmax(vals, axis=1)]
    keep = np.unique(np.concatenate([lo, hi, [0, n - 1]]))
    return t[keep], y[keep]


#: the units of the responses as drawn (F, T, Fy in SI; z in mm)
UNITS = {r.key: r.shown_in for r in RESPONSES}


def _steady_range(values: Sequence[np.ndarray], means: Sequence[float]) -> tuple[float, float]:
    """The y range that shows the misfit: the steady parts of the signals (inside their
    averaging windows, 1st to 99th percentile) and the means, with a sixth of the span as
    margin; the transients before the windows may run off it."""
    finite = [v[np.isfinite(v)] for v in values if v.size]
    pts = [np.percentile(v, [1.0, 99.0]) for v in finite if v.size]
    lo = min([*(p[0] for p in pts), *means])
    hi = max([*(p[1] for p in pts), *means])
    pad = (hi - lo) / 6.0 or max(abs(hi), 1.0) * 0.05
    return lo - pad, hi + pad


def fit_chart(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    title: str | None = None,
    responses: Sequence[str] = RESPONSE_KEYS,
    offsets: dict[str, float] | None = None,
) -> Chart:
    """One column per dataset, one row per response of ``responses`` that some dataset
    measured: the filtered measured signal with its steady mean over the experimental window,
    and the simulated signal with its mean over the simulation's window, both against the
    carriage's travel x = v t [m], which the lab and the model share (a 25 s simulation of a
    180 s log covers the first 25 s of travel: grouser periods agree). Summary datasets (no
    series) show their mean +- sd as a band; a response a dataset did not measure shows the
    simulation only. Each panel states both means with their units; the y range is that of
    the steady signals, so that a millimetre's misfit shows; one legend, in the first panel.
    ``offsets`` (response -> value in SI) are measurement offsets added to the simulated
    signal (e.g. a calibrated sinkage datum). Without a carriage speed (none in the dataset,
    no simulation) the axis is time."""
    rows = [
        row for row in _ROWS if row[0] in responses and any(row[0] in d.responses for d in datasets)
    ]
    if not rows:
        rows = [row for row in _ROWS if row[0] in responses] or [
            row for row in _ROWS if row[0] in DEFAULT_KEYS
        ]
    offsets = offsets or {}
    ncols = len(datasets)
    grid: list[list[Panel]] = [[] for _ in rows]
    for c, (ds, sim) in enumerate(zip(datasets, sims, strict=True)):
        rig = sim.rig if sim is not None else None
        v = ds.conditions.carriage_speed or (rig.carriage_speed if rig is not None else None)
        xscale, xlabel = (v, "carriage travel x [m]") if v else (1.0, "time t [s]")
        x_end = 0.0
        window = None  # the measured steady window [s], where the dataset has a time axis
        if ds.series is not None and ds.series.t.size:
            t_meas = ds.series.t
            window = ds.window if ds.window is not None else (float(t_meas[0]), float(t_meas[-1]))
            x_end = float(t_meas[-1]) * xscale
        column: list[Panel] = []
        for r, (key, col, ylabel, scale, offset_name) in enumerate(rows):
            panel = Panel(
                Axis(xlabel if r == len(rows) - 1 else "", tick_labels=r == len(rows) - 1),
                Axis(ylabel),
                title=f"{ds.name} ({condition_label(ds.conditions)})" if r == 0 else None,
                legend="lower right" if (r, c) == (0, 0) else None,
            )
            stat = ds.responses.get(key)
            steady: list[np.ndarray] = []
            means: list[float] = []
            said: list[str] = []
            if stat is None:
                panel.add(text("not measured", fy=0.08))
            elif window is not None:  # a measured time axis
                y_all = ds.series.filtered[col] * scale
                t, y = decimated(ds.series.t, y_all)
                lo, hi = window
                inside = (ds.series.t >= lo) & (ds.series.t <= hi)
                steady.append(y_all[inside])
                panel.add(
                    line(t * xscale, y, "mid", width=0.7, label="measured (filtered)"),
                    vspan(lo * xscale, hi * xscale, label="measured window"),
                    segment(lo * xscale, hi * xscale, stat.mean * scale, label="measured mean"),
                )
            else:
                panel.add(
                    hspan(
                        (stat.mean - stat.sd) * scale,
                        (stat.mean + stat.sd) * scale,
                        label="measured mean +- sd",
                    ),
                    hline(stat.mean * scale, "black", width=2.0),
                )
                means += [(stat.mean - stat.sd) * scale, (stat.mean + stat.sd) * scale]
            if stat is not None:
                means.append(stat.mean * scale)
                said.append(f"measured {stat.mean * scale:.4g} {UNITS[key]}")
            if rig is not None:
                ys, m, last = _simulated(panel, sim, key, scale, offset_name, offsets, ds, xscale)
                steady.append(ys)
                if m is not None:
                    means.append(m)
                    said.append(f"simulated {m:.4g} {UNITS[key]}")
                x_end = max(x_end, last)
            if said:
                panel.add(text(", ".join(said)))
            if steady or means:
                lo_y, hi_y = _steady_range(steady, means)
                panel.y = replace(panel.y, lo=lo_y, hi=hi_y)
            column.append(panel)
        for r, panel in enumerate(column):
            if x_end > 0:
                panel.x = replace(panel.x, lo=0.0, hi=x_end)
            grid[r].append(panel)
    return Chart(
        title or "Measured vs simulated at the MAP sample",
        [p for row in grid for p in row],
        columns=ncols,
        size=(max(5.2 * ncols, 8.0), 2.6 * len(rows) + 0.4),
        reflow="columns",  # a dataset's responses together on a narrow screen
    )


def _simulated(
    panel: Panel,
    sim: SWTResult,
    key: str,
    scale: float,
    offset_name: str,
    offsets: dict[str, float],
    ds: SWTDataset,
    xscale: float,
) -> tuple[np.ndarray, float | None, float]:
    """The simulated signal of ``key`` on ``panel``, raw and filtered, with its averaging
    window and steady mean, against x = ``xscale`` t. Returns the filtered signal inside the
    window, the mean (None if the run has none) and the last x drawn."""
    rig = sim.rig
    off = getattr(rig, offset_name)
    ts = sim.series["t"]
    ys = (sim.series[key] + offsets.get(key, 0.0)) * scale
    filtered = _filtered(ts, ys, ds.cutoff_hz)
    t_raw, y_raw = decimated(ts, ys)
    t_f, y_f = decimated(ts, filtered)
    w0, w1 = off * xscale, rig.duration * xscale
    panel.add(
        line(t_raw * xscale, y_raw, "blue", width=0.5, opacity=0.3),
        line(t_f * xscale, y_f, "blue", width=0.9, label="simulated (filtered)"),
        vspan(w0, w1, "blue", opacity=0.07, label="simulated window"),
    )
    mean = None
    if sim.means is not None:
        mean = (getattr(sim.means, key) + offsets.get(key, 0.0)) * scale
        panel.add(segment(w0, w1, mean, "red", label="simulated mean"))
    last = float(ts[-1]) * xscale if ts.size else w1
    return filtered[(ts >= off) & (ts <= rig.duration)], mean, last


def dataset_angle(ds: SWTDataset) -> float:
    """A dataset's slip angle [deg] (0 where none is given)."""
    return angle_of(ds.conditions)


def slip_fit_chart(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    title: str | None = None,
    responses: Sequence[str] = RESPONSE_KEYS,
    offsets: dict[str, float] | None = None,
    sigmas: Mapping[str, float] | None = None,
) -> Chart:
    """A steered study's fit at a parameter sample against the symmetric lab slip (-1 =
    locked): a column per slip angle, a row per response of ``responses`` that some dataset
    measured (:func:`services.plots.angles.angle_grid`). Each wheel's simulated steady means
    at its datasets' slips (a line through them) with the band of +- 1.96 sigma about them,
    where ``sigmas`` (response -> the prediction-error sigma at the sample, SI) gives one: 95 %
    of single tests fall in it if the model holds; the measured means with their +- sd bars
    (the trials' or the window's). ``offsets`` as in :func:`fit_chart`. The responses'
    signals in time are :func:`fit_chart`'s, a column per dataset: too many for a study of
    many conditions."""
    measured = {k for ds in datasets for k in ds.responses}
    rows = [r for r in _ROWS if r[0] in responses and r[0] in measured]
    pairs = [
        (ds, sim)
        for ds, sim in zip(datasets, sims, strict=True)
        if ds.conditions.slip_symmetric is not None
    ]
    wheels = list(dict.fromkeys(wheel_label(ds.conditions.to_sim_config()) for ds, _ in pairs))
    groups = dict(by_slip_angle(pairs, lambda pair: dataset_angle(pair[0])))

    def panel(row: tuple, angle: float, bottom: bool) -> Panel:
        key, _, label, scale, _ = row
        return _slip_fit_panel(
            key, label, scale, groups[angle], wheels, offsets or {}, sigmas or {}, bottom
        )

    return angle_grid(
        title or "Measured vs simulated steady means across slip",
        rows,
        sorted(groups),
        panel,
    )


def _slip_fit_panel(
    key: str,
    label: str,
    scale: float,
    pairs: Sequence[tuple[SWTDataset, SWTResult | None]],
    wheels: Sequence[str],
    offsets: Mapping[str, float],
    sigmas: Mapping[str, float],
    bottom: bool,
) -> Panel:
    """One response at one slip angle of :func:`slip_fit_chart` (``pairs``: the angle's
    datasets with their simulations; the grid places the legend)."""
    panel = Panel(Axis(SLIP_LABEL if bottom else "", tick_labels=bottom), Axis(label))
    panel.add(vline(0.0, "grey", width=0.6))
    several = len(wheels) > 1
    sigma = sigmas.get(key)
    mine = sorted(pairs, key=lambda pair: pair[0].conditions.slip_symmetric)
    for w, wheel in enumerate(wheels):
        own = [(ds, sim) for ds, sim in mine if wheel_label(ds.conditions.to_sim_config()) == wheel]
        if not own:
            continue
        color = WHEEL_COLORS[w % len(WHEEL_COLORS)] if several else "blue"
        who = f"{wheel}: " if several else ""
        x = np.array([ds.conditions.slip_symmetric for ds, _ in own])
        sim = np.array(
            [
                (getattr(s.means, key) + offsets.get(key, 0.0)) * scale
                if s is not None and s.means is not None
                else np.nan
                for _, s in own
            ]
        )
        if sigma is not None and np.isfinite(sigma):
            half = Z95 * sigma * scale
            panel.add(
                band(x, sim - half, sim + half, color, label=f"{who}simulated +- 1.96 sigma (95 %)")
            )
        panel.add(line(x, sim, color, width=1.5, marker="o", label=f"{who}simulated mean"))
        got = [
            (xi, ds.responses[key])
            for xi, (ds, _) in zip(x, own, strict=True)
            if key in ds.responses
        ]
        if got:
            xs = [xi for xi, _ in got]
            means = [st.mean * scale for _, st in got]
            sd = [(st.sd if np.isfinite(st.sd) else 0.0) * scale for _, st in got]
            panel.add(
                errorbars(
                    xs,
                    means,
                    [m - d for m, d in zip(means, sd, strict=True)],
                    [m + d for m, d in zip(means, sd, strict=True)],
                    "black" if not several else color,
                    label=f"{who}measured mean +- sd",
                ),
                points(xs, means, "black" if not several else color, size=3.5, opacity=1.0),
            )
    if not any(key in ds.responses for ds, _ in mine):
        panel.add(text("not measured"))
    return panel


def fits_against_slip(datasets: Sequence[SWTDataset]) -> bool:
    """Whether a study's fit is its steady means against slip, a column per slip angle
    (:func:`slip_fit_chart`: a dataset of known slip is steered), rather than each dataset's
    signals in time (:func:`fit_chart`, Figure 3)."""
    on_slip = [d for d in datasets if d.conditions.slip_symmetric is not None]
    return steered(on_slip, dataset_angle)


def plot_fit(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    path: str | Path,
    **options: Any,
) -> Path:
    """:func:`fit_chart` drawn to ``path``."""
    from .mpl import draw

    return save(draw(fit_chart(datasets, sims, **options)), path)


def plot_slip_fit(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    path: str | Path,
    **options: Any,
) -> Path:
    """:func:`slip_fit_chart` drawn to ``path``."""
    from .mpl import draw

    return save(draw(slip_fit_chart(datasets, sims, **options)), path)
