"""Simulated vs measured SWT signals at a parameter sample (e.g. the MAP), like Figure 3."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from scm_core.signals import SWTDataset, TestConditions, lowpass
from scm_core.simulator import SWTResult

from .chart import Axis, Chart, Panel, hline, hspan, line, segment, text, vspan
from .figures import save

#: points per drawn curve at most: about two per pixel column of a panel (5.2 in at 100-120 dpi);
#: a 180 s lab log at 100 Hz drawn in full made one figure 254 KB of SVG (issue 45)
MAX_POINTS = 1200

_ROWS = (
    ("F", "drawbar_pull", "drawbar pull F [N]", 1.0, "offset_F"),
    ("T", "torque", "torque T [N m]", 1.0, "offset_T"),
    ("z", "sinkage", "sinkage z [mm]", 1000.0, "offset_z"),
)


def condition_label(c: TestConditions) -> str:
    """'slip 0.2, W 315 N' (the symmetric lab slip; 'locked' for a locked wheel)."""
    if c.slip_symmetric is None:
        kin = "slip ?"
    elif c.slip_symmetric <= -1.0:
        kin = "locked"
    else:
        kin = f"slip {c.slip_symmetric:.3g}"
    return f"{kin}, W {c.W:g} N"


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


def _window_map(
    measured: tuple[float, float], simulated: tuple[float, float]
) -> tuple[float, float]:
    """(a, b) with measured time = a + b * simulated time, mapping the simulation's averaging
    window onto the measured one (their steady windows overlay)."""
    (lo, hi), (s0, s1) = measured, simulated
    b = (hi - lo) / (s1 - s0) if s1 > s0 else 1.0
    return lo - b * s0, b


def fit_chart(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    title: str | None = None,
    responses: Sequence[str] = ("F", "T", "z"),
    offsets: dict[str, float] | None = None,
) -> Chart:
    """One column per dataset, one row per response of ``responses`` that some dataset
    measured: the filtered measured signal with its steady mean over the experimental window,
    and the simulated signal with its mean over the simulation's windows (both windows
    shaded). Summary datasets (no series) show their mean +- sd as a band; a response a
    dataset did not measure shows the simulation only. ``offsets`` (response -> value in SI)
    are measurement offsets added to the simulated signal (e.g. a calibrated sinkage datum).
    A column's panels share their time axis (tick labels under the bottom one)."""
    rows = [
        row for row in _ROWS if row[0] in responses and any(row[0] in d.responses for d in datasets)
    ]
    if not rows:
        rows = [row for row in _ROWS if row[0] in responses] or list(_ROWS)
    offsets = offsets or {}
    ncols = len(datasets)
    grid: list[list[Panel]] = [[] for _ in rows]
    for ds, sim in zip(datasets, sims, strict=True):
        t_start, t_end = 0.0, 0.0  # the time axis drawn [s]
        window = None  # the measured steady window, where the dataset has a time axis
        if ds.series is not None and ds.series.t.size:
            t_meas = ds.series.t
            window = ds.window if ds.window is not None else (float(t_meas[0]), float(t_meas[-1]))
            t_end = float(t_meas[-1])
        column: list[Panel] = []
        for r, (key, col, ylabel, scale, offset_name) in enumerate(rows):
            bottom = r == len(rows) - 1
            panel = Panel(
                Axis(
                    ("time t [s]" if window is None else "measured time t [s]") if bottom else "",
                    tick_labels=bottom,
                ),
                Axis(ylabel),
                title=f"{ds.name} ({condition_label(ds.conditions)})" if r == 0 else None,
                legend="lower right",
            )
            stat = ds.responses.get(key)
            if stat is None:
                panel.add(text("not measured"))
            elif window is not None:  # a measured time axis
                t, y = decimated(ds.series.t, ds.series.filtered[col] * scale)
                lo, hi = window
                panel.add(
                    line(t, y, "mid", width=0.7, label="measured (filtered)"),
                    vspan(lo, hi, label="measured window"),
                    segment(
                        lo, hi, stat.mean * scale, label=f"measured mean {stat.mean * scale:.4g}"
                    ),
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
            if sim is not None and sim.rig is not None:
                first, last = _simulated(panel, sim, key, scale, offset_name, offsets, ds, window)
                t_start, t_end = min(t_start, first), max(t_end, last)
                if window is not None and r == 0:
                    a, b = _window_map(window, (getattr(sim.rig, offset_name), sim.rig.duration))
                    panel.top = ("simulated time [s]", a, b)
            column.append(panel)
        for r, panel in enumerate(column):
            if t_end > 0:
                panel.x = replace(panel.x, lo=t_start, hi=t_end)
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
    window: tuple[float, float] | None,
) -> tuple[float, float]:
    """The simulated signal of ``key`` on ``panel``, raw and filtered, with its averaging
    window and steady mean. Where the dataset has a measured time axis (``window``: its steady
    window), the simulation's time is mapped linearly so that its averaging window lies over
    the measured one (a 12 s simulation of a 180 s log then spans the log's window instead of
    the first 7 % of the axis; the panel's top axis gives the simulated time). Returns the
    first and last times drawn, on the measured axis [s]."""
    rig = sim.rig
    off = getattr(rig, offset_name)
    a, b = (0.0, 1.0) if window is None else _window_map(window, (off, rig.duration))
    ts = sim.series["t"]
    ys = (sim.series[key] + offsets.get(key, 0.0)) * scale
    t_raw, y_raw = decimated(ts, ys)
    t_f, y_f = decimated(ts, _filtered(ts, ys, ds.cutoff_hz))
    w0, w1 = a + b * off, a + b * rig.duration
    panel.add(
        line(a + b * t_raw, y_raw, "blue", width=0.5, opacity=0.3),
        line(a + b * t_f, y_f, "blue", width=0.9, label="simulated (filtered)"),
        vspan(w0, w1, "blue", opacity=0.07, label="simulated window"),
    )
    if sim.means is not None:
        m = (getattr(sim.means, key) + offsets.get(key, 0.0)) * scale
        panel.add(segment(w0, w1, m, "red", label=f"simulated mean {m:.4g}"))
    return a + b * float(ts[0]) if ts.size else w0, w1


def plot_fit(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    path: str | Path,
    **options: Any,
) -> Path:
    """:func:`fit_chart` drawn to ``path``."""
    from .mpl import draw

    return save(draw(fit_chart(datasets, sims, **options)), path)
