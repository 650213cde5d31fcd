"""Figure of a simulated (or measured) SWT like the paper's Figure 3."""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

from scm_core.simulator import SWTResult

_PANELS = (
    ("F", "drawbar pull F [N]", 1.0, "offset_F"),
    ("T", "torque T [N m]", 1.0, "offset_T"),
    ("z", "sinkage z [mm]", 1000.0, "offset_z"),
)


def plot_swt(result: SWTResult, path: str | Path, title: str | None = None) -> Path:
    """Draw F, T and z against time with the averaging windows shaded and the means marked."""
    path = Path(path)
    rig = result.rig
    fig = Figure(figsize=(8, 7.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    t = result.series["t"]
    for ax, (key, label, scale, offset_name) in zip(axes, _PANELS, strict=True):
        ax.plot(t, result.series[key] * scale, lw=0.8, color="tab:blue", label="simulation")
        offset = getattr(rig, offset_name)
        ax.axvspan(offset, rig.duration, color="tab:orange", alpha=0.12, label="averaging window")
        if result.means is not None:
            mean = getattr(result.means, key) * scale
            ax.hlines(
                mean, offset, rig.duration, colors="tab:red", lw=2.0, label=f"mean {mean:.3g}"
            )
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    axes[0].set_title(title or f"SCM single-wheel test ({result.status})")
    fig.savefig(path, dpi=120)
    return path
