"""Morris indices per response, like the paper's Figure 4."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from scm_core.signals.responses import DEFAULT_KEYS, response

from .figures import save


def indices_figure(
    names: Sequence[str],
    linear_index: NDArray[np.float64],
    nonlinear_index: NDArray[np.float64],
    title: str,
    keys: Sequence[str] = DEFAULT_KEYS,
) -> Figure:
    """Grouped bars per factor: normalised linear index mu* / sum mu* and non-linear index
    sigma / sum sigma (tables factor x response of ``keys``: F, T, z, and Fy for a steered
    wheel), one panel per response."""
    names = list(names)
    linear_index = np.asarray(linear_index, dtype=float)
    nonlinear_index = np.asarray(nonlinear_index, dtype=float)
    x = np.arange(len(names))
    fig = Figure(figsize=(4 * len(keys), 3.8), layout="constrained")
    axes = fig.subplots(1, len(keys), sharey=True)
    labels = [f"{response(r).words} {r}" for r in keys]
    for k, (ax, label) in enumerate(zip(axes, labels, strict=True)):
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


def stored_indices_figure(doc: Mapping[str, Any], title: str, note: str = "") -> Figure:
    """The bars of :func:`indices_figure` from a stored result document
    (:meth:`SensitivityResult.to_dict`: tables response -> factor -> index, null for NaN;
    a panel per response it reports); ``title`` is followed by its settings and run counts,
    then ``note``."""
    names = [f["name"] for f in doc["factors"]]
    keys = list(doc["responses"])

    def table(key: str) -> NDArray[np.float64]:
        t = doc[key]
        return np.array(
            [[np.nan if t[r][n] is None else t[r][n] for r in keys] for n in names],
            dtype=float,
        )

    return indices_figure(
        names,
        table("linear_index"),
        table("nonlinear_index"),
        f"{title} (r = {doc['r']}, {doc['levels']} levels, {doc['n_runs']} runs, "
        f"{doc['n_failed_runs']} failed){note}",
        keys,
    )


def plot_indices(doc: Mapping[str, Any], path: str | Path, title: str = "Morris screening") -> Path:
    """:func:`stored_indices_figure` saved to ``path``."""
    return save(stored_indices_figure(doc, title), path)
