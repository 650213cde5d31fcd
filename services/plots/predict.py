"""Posterior predictions against slip: F, T, z with their 95 % bands and the measured points."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from scm_core.calibration.predict import ConditionPrediction

from .figures import save

_PANELS = (
    ("F", "drawbar pull F [N]", 1.0),
    ("T", "torque T [N m]", 1.0),
    ("z", "sinkage z [mm]", 1000.0),
)
_ROLE_STYLE = {
    "calibration": ("o", "k", "measured, used in the calibration"),
    "predicted": ("s", "tab:red", "measured, held out"),
}


def predictions_figure(
    datasets: Sequence[ConditionPrediction],
    sweep: Sequence[ConditionPrediction],
    title: str | None = None,
    responses: Sequence[str] = ("F", "T", "z"),
) -> Figure:
    """One panel per response against the symmetric lab slip (-1 = locked): the sweep's
    median and 95 % bands (simulated means, and with the prediction-error noise), each
    dataset's predicted median (a tick) and 95 % predictive interval (the bar), and its
    measurement where it has one (filled: used in the calibration; squares: held out)."""
    panels = [p for p in _PANELS if p[0] in responses]
    fig = Figure(figsize=(7.0, 2.6 * len(panels) + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    sw = sorted((c for c in sweep if c.slip_symmetric is not None), key=lambda c: c.slip_symmetric)
    for ax, (key, label, scale) in zip(axes, panels, strict=True):
        if sw:
            s = np.array([c.slip_symmetric for c in sw])
            med = np.array([c.responses[key].simulated.median for c in sw]) * scale
            lo = np.array([c.responses[key].simulated.lo for c in sw]) * scale
            hi = np.array([c.responses[key].simulated.hi for c in sw]) * scale
            pred = [c.responses[key].predictive for c in sw]
            if all(p is not None for p in pred):
                plo = np.array([p.lo for p in pred]) * scale
                phi = np.array([p.hi for p in pred]) * scale
                ax.fill_between(
                    s,
                    plo,
                    phi,
                    color="tab:blue",
                    alpha=0.12,
                    lw=0,
                    label="95 % predictive band (with model error)",
                )
            ax.fill_between(
                s,
                lo,
                hi,
                color="tab:blue",
                alpha=0.3,
                lw=0,
                label="95 % band of the simulated mean",
            )
            ax.plot(s, med, color="tab:blue", lw=1.5, label="posterior median")
        shown = set()
        for c in datasets:
            if c.slip_symmetric is None:
                continue
            r = c.responses[key]
            band = r.predictive or r.simulated
            kind = "predictive interval" if r.predictive is not None else "band of the mean"
            ax.errorbar(
                c.slip_symmetric,
                band.median * scale,
                yerr=[[(band.median - band.lo) * scale], [(band.hi - band.median) * scale]],
                fmt="_",
                color="tab:blue",
                ms=9,
                elinewidth=1.0,
                capsize=3,
                label=None if "bar" in shown else f"predicted median, 95 % {kind}",
            )
            shown.add("bar")
            if r.measured is not None:
                marker, color, lab = _ROLE_STYLE.get(c.role, _ROLE_STYLE["predicted"])
                ax.plot(
                    c.slip_symmetric,
                    r.measured * scale,
                    marker,
                    color=color,
                    ms=5,
                    label=None if c.role in shown else lab,
                    zorder=5,
                )
                shown.add(c.role)
        if not any(c.responses[key].measured is not None for c in datasets):
            ax.text(0.02, 0.92, "no measurement", transform=ax.transAxes, fontsize=8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.axvline(0.0, color="0.6", lw=0.6)
    axes[0].legend(fontsize=7, loc="best")
    axes[-1].set_xlabel("slip (omega r - v) / max(v, omega r)  [-1 = locked]")
    fig.suptitle(title or "Posterior predictions across slip")
    return fig


def plot_predictions(
    datasets: Sequence[ConditionPrediction],
    sweep: Sequence[ConditionPrediction],
    path: str | Path,
    title: str | None = None,
    responses: Sequence[str] = ("F", "T", "z"),
) -> Path:
    """:func:`predictions_figure` saved to ``path``."""
    return save(predictions_figure(datasets, sweep, title, responses), path, dpi=120)
