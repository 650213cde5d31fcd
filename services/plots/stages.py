"""The TMCMC schedule of a study: tempering exponent and acceptance rate per stage."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

__all__ = ["schedule_figure"]


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
