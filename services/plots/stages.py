"""A study's stages: the TMCMC schedule (tempering exponent, acceptance rate) and each
parameter's population from the prior to the posterior (TMCMC's trace plot)."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from .chart import Axis, Chart, Panel, band, hline, line

__all__ = ["schedule_chart", "stage_trace_chart"]


def schedule_chart(
    stages: Sequence[int],
    exponents: Sequence[float | None],
    acceptance: Sequence[float | None],
    ess: Sequence[float | None] | None = None,
    n_samples: int | None = None,
    title: str | None = None,
) -> Chart:
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
    pos = p > 0
    exponent = Panel(
        Axis("stage j", integer=True),
        Axis("tempering exponent p_j [-]", scale="log"),
        legend="lower right",
    ).add(
        line(j[pos], p[pos], "blue", marker="o", label="exponent p_j"),
        hline(1.0, "grey", dash="dashed", label="posterior (p = 1)"),
    )
    ok = np.isfinite(acc)
    rates = Panel(
        Axis("stage j", integer=True), Axis("fraction [-]", lo=0.0, hi=1.0), legend="upper right"
    ).add(line(j[ok], acc[ok], "orange", marker="s", label="acceptance rate"))
    if ess is not None and n_samples:
        e = arr(ess) / float(n_samples)
        fin = np.isfinite(e)
        rates.add(line(j[fin], e[fin], "green", dash="dashed", marker="^", label="ESS / N"))
    return Chart(title or "TMCMC schedule", [exponent, rates], columns=2, size=(9.0, 3.4))


def stage_trace_chart(
    names: Sequence[str],
    stages: Sequence[int],
    populations: Sequence[NDArray[np.float64]],
    units: Mapping[str, str] | None = None,
    log_params: Collection[str] = (),
    title: str | None = None,
) -> Chart:
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
    panels: list[Panel | None] = []
    for k, name in enumerate(names):
        unit = (units or {}).get(name, "")
        panels.append(
            Panel(
                Axis("stage j", integer=True),
                Axis(
                    f"{name} [{unit}]" if unit not in ("", "-") else name,
                    scale="log" if name in log_params else "linear",
                ),
                legend="best" if k == 0 else None,
            ).add(
                band(j, q[:, 0, k], q[:, 4, k], "blue", opacity=0.18, label="95 %"),
                band(j, q[:, 1, k], q[:, 3, k], "blue", opacity=0.35, label="50 %"),
                line(j, q[:, 2, k], "blue", marker="o", label="median"),
            )
        )
    nrows = math.ceil(d / ncols)
    return Chart(
        title or "Population per stage: median, 50 % and 95 % intervals",
        panels,
        columns=ncols,
        size=(3.2 * ncols, 2.4 * nrows + 0.5),
    )
