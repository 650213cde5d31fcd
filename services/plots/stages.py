"""A study's stages: the TMCMC schedule (tempering exponent, acceptance rate) and each
parameter's population from the prior to the posterior (TMCMC's trace plot)."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

__all__ = ["schedule_figure", "stage_trace_figure"]


def schedule_figure(
    stages: Sequence[int],
    exponents: Sequence[float | None],
    acceptance: Sequence[float | None],
    ess: Sequence[float | None] | None = None,
    n_samples: int | None = None,
    title: str | None = None,
) -> Figure:
    """Two panels against the stage index: the exponent p_j (log axis: the schedule's early
    stages are orders of magnitude below 1) and the Metropolis acceptance rate with, if
    given, ESS / N of the stage's weights (eq. (9)'s target is ESS / N = 0.5 in the
    plausibility-weight schedule). Missing values (a stage not done) are left out."""
    j = np.asarray(stages, dtype=float)

    def arr(v: Sequence[float | None] | None) -> np.ndarray:
        if v is None:
            return np.full(j.size, np.nan)
        return np.array([np.nan if x is None else float(x) for x in v])

    p, acc = arr(exponents), arr(acceptance)
    fig = Figure(figsize=(9.0, 3.4), layout="constrained")
    ax_p, ax_a = fig.subplots(1, 2)
    pos = p > 0
    ax_p.semilogy(j[pos], p[pos], "o-", color="tab:blue", label="exponent p_j")
    ax_p.axhline(1.0, color="0.5", lw=0.8, ls="--", label="posterior (p = 1)")
    ax_p.set_xlabel("stage j")
    ax_p.set_ylabel("tempering exponent p_j [-]")
    ax_p.grid(alpha=0.3, which="both")
    ax_p.legend(fontsize=8, loc="lower right")
    ok = np.isfinite(acc)
    ax_a.plot(j[ok], acc[ok], "s-", color="tab:orange", label="acceptance rate")
    if ess is not None and n_samples:
        e = arr(ess) / float(n_samples)
        ax_a.plot(j[np.isfinite(e)], e[np.isfinite(e)], "^--", color="tab:green", label="ESS / N")
    ax_a.set_ylim(0.0, 1.0)
    ax_a.set_xlabel("stage j")
    ax_a.set_ylabel("fraction [-]")
    ax_a.grid(alpha=0.3)
    ax_a.legend(fontsize=8, loc="upper right")
    for ax in (ax_p, ax_a):
        ax.xaxis.get_major_locator().set_params(integer=True)
    fig.suptitle(title or "TMCMC schedule")
    return fig


def stage_trace_figure(
    names: Sequence[str],
    stages: Sequence[int],
    populations: Sequence[NDArray[np.float64]],
    units: Mapping[str, str] | None = None,
    log_params: Collection[str] = (),
    title: str | None = None,
) -> Figure:
    """One panel per parameter against the stage index: the population's median, central 50 %
    and 95 % intervals (TMCMC's trace: each stage is an equally weighted sample of the
    tempered posterior p(theta) L(theta)^p_j, from the prior at stage 0 to the posterior).
    A posterior that converged flattens out over the last stages; one still moving, or
    pressed against a prior bound, shows it. ``populations[k]`` (n, d) is stage ``stages[k]``;
    parameters in ``log_params`` are drawn on log axes."""
    j = np.asarray(stages, dtype=float)
    q = np.array([np.nanquantile(x, [0.025, 0.25, 0.5, 0.75, 0.975], axis=0) for x in populations])
    d = len(names)
    ncols = min(4, d)
    nrows = math.ceil(d / ncols)
    fig = Figure(figsize=(3.2 * ncols, 2.4 * nrows + 0.5), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for k, (ax, name) in enumerate(zip(axes, names, strict=False)):
        ax.fill_between(j, q[:, 0, k], q[:, 4, k], color="tab:blue", alpha=0.18, lw=0, label="95 %")
        ax.fill_between(j, q[:, 1, k], q[:, 3, k], color="tab:blue", alpha=0.35, lw=0, label="50 %")
        ax.plot(j, q[:, 2, k], "o-", color="tab:blue", ms=3, lw=1.2, label="median")
        if name in log_params:
            ax.set_yscale("log")
        unit = (units or {}).get(name, "")
        ax.set_ylabel(f"{name} [{unit}]" if unit not in ("", "-") else name)
        ax.set_xlabel("stage j")
        ax.xaxis.get_major_locator().set_params(integer=True)
        ax.grid(alpha=0.3)
    for ax in axes[d:]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(title or "Population per stage: median, 50 % and 95 % intervals")
    return fig
