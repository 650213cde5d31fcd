"""Rank plots of repeated runs (ArviZ's ``plot_rank``): do independent runs sample the same
posterior?"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from scm_core.arviz_import import arviz

__all__ = ["rank_figure"]


def rank_figure(
    names: Sequence[str],
    chains: NDArray[np.float64],
    labels: Sequence[str] | None = None,
    title: str | None = None,
) -> Figure:
    """One panel per parameter: the histogram of each run's ranks in the pooled draws
    (``chains`` (K, n, d): K runs of n equally weighted samples; Vehtari et al. 2021). Runs of
    one posterior give flat, overlapping histograms (the dashed line is the uniform count);
    a run whose bars rise at one end sits higher or lower than the others."""
    az = arviz()  # slow to import; only here

    k, _, d = chains.shape
    ncols = min(4, d)
    nrows = math.ceil(d / ncols)
    fig = Figure(figsize=(3.2 * ncols, 2.5 * nrows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # ArviZ 0.23's notice of its 1.0
        data = az.from_dict(posterior={n: chains[:, :, j] for j, n in enumerate(names)})
        az.plot_rank(data, var_names=list(names), ax=axes[:d], kind="bars")
    for ax in axes[d:]:
        ax.set_visible(False)
    runs = list(labels) if labels is not None else [f"run {i + 1}" for i in range(k)]
    for ax in axes[:d]:
        # ArviZ stacks run i's histogram from height i (its dashed line: the uniform count)
        ax.set_yticks(ax.get_yticks()[:k], runs, fontsize=7)
        ax.set_ylabel("")
        ax.set_xlabel("rank in the pooled draws", fontsize=8)
        ax.title.set_fontsize(10)
        ax.tick_params(axis="x", labelsize=7)
    fig.suptitle(title or f"Rank plots of {k} runs")
    return fig
