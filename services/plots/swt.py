"""Figure of a simulated (or measured) SWT like the paper's Figure 3."""

from __future__ import annotations

from pathlib import Path

from scm_core.signals import SWTDataset
from scm_core.signals.responses import RESPONSES, keys_of
from scm_core.simulator import SWTResult, WheelGeometry

from .chart import Axis, Chart, Panel, line, segment, vspan
from .fit import UNITS, condition_label, decimated, wheel_label

_PANELS = tuple((r.key, r.label, r.scale, r.offset) for r in RESPONSES)


def conditions_text(result: SWTResult, wheel: WheelGeometry | None = None) -> str:
    """'slip 0.2, W 315 N, v 10 mm/s; wheel R 125 mm, b 112 mm, 12 grousers of 9 mm'."""
    rig = result.rig
    text = f"{condition_label(rig)}, v {1000 * rig.carriage_speed:.3g} mm/s"
    return text if wheel is None else f"{text}; wheel {wheel_label(wheel.model_dump())}"


def swt_figure(result: SWTResult, title: str | None = None, wheel: WheelGeometry | None = None):
    """F, T and z (and Fy, for a steered wheel) against time with the averaging windows shaded
    and the means marked (with their units); the title gives the test conditions (and the
    wheel, when given)."""
    from matplotlib.figure import Figure

    rig = result.rig
    keys = keys_of(bool(rig.slip_angle))
    panels = [p for p in _PANELS if p[0] in keys]
    fig = Figure(figsize=(8, 2.5 * len(panels)), layout="constrained")
    axes = fig.subplots(len(panels), 1, sharex=True)
    t = result.series["t"]
    for ax, (key, label, scale, offset_name) in zip(axes, panels, strict=True):
        ax.plot(t, result.series[key] * scale, lw=0.8, color="tab:blue", label="simulation")
        offset = getattr(rig, offset_name)
        ax.axvspan(offset, rig.duration, color="tab:orange", alpha=0.12, label="averaging window")
        if result.means is not None:
            mean = getattr(result.means, key) * scale
            ax.hlines(
                mean,
                offset,
                rig.duration,
                colors="tab:red",
                lw=2.0,
                label=f"mean {mean:.4g} {UNITS[key]}",
            )
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    axes[0].set_title(
        title or f"SCM single-wheel test ({result.status})\n{conditions_text(result, wheel)}",
        fontsize=10,
    )
    return fig


def plot_swt(
    result: SWTResult,
    path: str | Path,
    title: str | None = None,
    wheel: WheelGeometry | None = None,
) -> Path:
    """:func:`swt_figure` saved to ``path`` (PNG)."""
    path = Path(path)
    swt_figure(result, title, wheel).savefig(path, dpi=120)
    return path


_MEASURED = tuple((r.key, r.column, r.label, r.scale) for r in RESPONSES)


def measured_chart(ds: SWTDataset, title: str | None = None) -> Chart:
    """A lab log's channels against time: raw (light) and low-pass filtered, the averaging
    window shaded and the steady mean marked. Each line is min-max decimated to what a panel's
    pixel columns show (:func:`~services.plots.fit.decimated`: every peak kept; the means are
    those of all samples)."""
    if ds.series is None:
        raise ValueError(f"dataset {ds.name!r} has no series (a summary dataset)")
    s = ds.series
    rows = [r for r in _MEASURED if r[1] in s.raw]
    panels: list[Panel | None] = []
    for k, (key, column, label, scale) in enumerate(rows):
        bottom = k == len(rows) - 1
        panel = Panel(
            Axis("time t [s]" if bottom else "", tick_labels=bottom),
            Axis(label),
            legend="lower right",
        ).add(
            line(*decimated(s.t, s.raw[column] * scale), "light", width=0.4, label="raw"),
            line(*decimated(s.t, s.filtered[column] * scale), width=0.9, label="filtered"),
        )
        if ds.window is not None:
            panel.add(vspan(*ds.window, "orange", opacity=0.12, label="averaging window"))
            stat = ds.responses.get(key)
            if stat is not None:
                m = stat.mean * scale
                panel.add(segment(*ds.window, m, "red", width=2.0, label=f"mean {m:.4g}"))
        panels.append(panel)
    cut = f", low-pass {ds.cutoff_hz:g} Hz" if ds.cutoff_hz else ""
    return Chart(
        title or f"{ds.name}: measured signals{cut}",
        panels,
        columns=1,
        size=(8.0, 2.3 * len(rows) + 0.5),
    )
