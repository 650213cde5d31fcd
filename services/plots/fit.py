"""Simulated vs measured SWT signals at a parameter sample (e.g. the MAP), like Figure 3."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from scm_core.signals import SWTDataset, TestConditions, lowpass
from scm_core.simulator import SWTResult

from .figures import save

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


def fit_figure(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    title: str | None = None,
    responses: Sequence[str] = ("F", "T", "z"),
    offsets: dict[str, float] | None = None,
) -> Figure:
    """One column per dataset, one row per response of ``responses`` that some dataset
    measured: the filtered measured signal with its steady mean over the experimental window,
    and the simulated signal with its mean over the simulation's windows (both windows
    shaded). Summary datasets (no
    series) show their mean +- sd as a band; a response a dataset did not measure shows the
    simulation only. ``offsets`` (response -> value in SI) are measurement offsets added to the
    simulated signal (e.g. a calibrated sinkage datum)."""
    rows = [
        row for row in _ROWS if row[0] in responses and any(row[0] in d.responses for d in datasets)
    ]
    if not rows:
        rows = [row for row in _ROWS if row[0] in responses] or list(_ROWS)
    offsets = offsets or {}
    ncols = len(datasets)
    fig = Figure(figsize=(max(5.2 * ncols, 8.0), 2.6 * len(rows) + 0.4), layout="constrained")
    axes = np.array(fig.subplots(len(rows), ncols, squeeze=False))
    for c, (ds, sim) in enumerate(zip(datasets, sims, strict=True)):
        t_end = 0.0
        rig = None if sim is None else sim.rig
        for r, (key, column, ylabel, scale, offset_name) in enumerate(rows):
            ax = axes[r, c]
            stat = ds.responses.get(key)
            if stat is None:
                ax.text(0.02, 0.95, "not measured", transform=ax.transAxes, va="top", fontsize=8)
            elif ds.series is not None:
                t = ds.series.t
                ax.plot(
                    t,
                    ds.series.filtered[column] * scale,
                    lw=0.7,
                    color="0.35",
                    label="measured (filtered)",
                )
                lo, hi = ds.window if ds.window is not None else (float(t[0]), float(t[-1]))
                ax.axvspan(lo, hi, color="0.5", alpha=0.08, lw=0, label="measured window")
                ax.hlines(
                    stat.mean * scale,
                    lo,
                    hi,
                    colors="k",
                    lw=2.2,
                    label=f"measured mean {stat.mean * scale:.4g}",
                )
                t_end = max(t_end, float(t[-1]))
            else:
                ax.axhspan(
                    (stat.mean - stat.sd) * scale,
                    (stat.mean + stat.sd) * scale,
                    color="0.8",
                    alpha=0.6,
                    label="measured mean +- sd",
                )
                ax.axhline(stat.mean * scale, color="k", lw=2.0)
            if sim is not None and rig is not None:
                ts = sim.series["t"]
                ys = (sim.series[key] + offsets.get(key, 0.0)) * scale
                ax.plot(ts, ys, lw=0.5, color="tab:blue", alpha=0.3)
                ax.plot(
                    ts,
                    _filtered(ts, ys, ds.cutoff_hz),
                    lw=0.9,
                    color="tab:blue",
                    label="simulated (filtered)",
                )
                ax.axvspan(
                    getattr(rig, offset_name),
                    rig.duration,
                    color="tab:blue",
                    alpha=0.07,
                    lw=0,
                    label="simulated window",
                )
                if sim.means is not None:
                    m = (getattr(sim.means, key) + offsets.get(key, 0.0)) * scale
                    ax.hlines(
                        m,
                        getattr(rig, offset_name),
                        rig.duration,
                        colors="tab:red",
                        lw=2.2,
                        label=f"simulated mean {m:.4g}",
                    )
                t_end = max(t_end, rig.duration)
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="lower right")
        axes[0, c].set_title(f"{ds.name} ({condition_label(ds.conditions)})")
        axes[-1, c].set_xlabel("time t [s]")
        if t_end > 0:
            for r in range(len(rows)):
                axes[r, c].set_xlim(0, t_end)
    fig.suptitle(title or "Measured vs simulated at the MAP sample")
    return fig


def plot_fit(
    datasets: Sequence[SWTDataset],
    sims: Sequence[SWTResult | None],
    path: str | Path,
    **options: Any,
) -> Path:
    """:func:`fit_figure` saved to ``path``."""
    return save(fit_figure(datasets, sims, **options), path)
