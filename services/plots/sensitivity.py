"""Morris indices per response, like the paper's Figure 4."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from scm_core.calibration import SensitivityResult

from .figures import save

_RESPONSES = (("F", "drawbar pull F"), ("T", "torque T"), ("z", "sinkage z"))


def morris_figure(result: SensitivityResult, title: str | None = None) -> Figure:
    """Grouped bars per factor: normalised linear index mu* / sum mu* and non-linear index
    sigma / sum sigma, one panel per response."""
    return indices_figure(
        result.names,
        result.linear_index,
        result.nonlinear_index,
        title
        or f"Morris screening (r = {result.r}, {result.levels} levels, "
        f"{result.n_runs} runs, {result.n_failed} failed)",
    )


def indices_figure(
    names: Sequence[str],
    linear_index: NDArray[np.float64],
    nonlinear_index: NDArray[np.float64],
    title: str,
) -> Figure:
    """The bars of :func:`morris_figure` from the index tables (factor x response F, T, z)."""
    names = list(names)
    linear_index = np.asarray(linear_index, dtype=float)
    nonlinear_index = np.asarray(nonlinear_index, dtype=float)
    x = np.arange(len(names))
    fig = Figure(figsize=(12, 3.8), layout="constrained")
    axes = fig.subplots(1, 3, sharey=True)
    for k, (ax, (_, label)) in enumerate(zip(axes, _RESPONSES, strict=True)):
        lin = np.nan_to_num(linear_index[:, k])
        non = np.nan_to_num(nonlinear_index[:, k])
        ax.bar(x - 0.2, lin, width=0.4, color="tab:blue", label="linear (mu*)")
        ax.bar(x + 0.2, non, width=0.4, color="tab:orange", label="non-linear (sigma)")
        ax.set_xticks(x, names, rotation=30)
        ax.set_title(label)
        ax.set_ylim(0, 1)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("normalised index")
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    return fig


def plot_morris(result: SensitivityResult, path: str | Path, title: str | None = None) -> Path:
    """:func:`morris_figure` saved to ``path``."""
    return save(morris_figure(result, title), path)
