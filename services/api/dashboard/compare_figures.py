"""The compare page's figures: several studies' posteriors side by side and pooled (Figure 9)
and rank plots of runs of one calibration, made from what the store holds (cached like the
study figures, :class:`~services.api.dashboard.study_figures.FigureCache`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import services.plots as plots  # submodules (matplotlib) load when a figure is drawn
from scm_core.inference.posterior import pool_samples
from services.store import Store, StudyRecord
from services.studies.comparable import why_not_runs
from services.studies.kinds import study_terms
from services.studies.kinds.base import stored_case

from .study_figures import FigureCache, FigureError, log_params, stage_data

__all__ = ["compare", "final_populations", "ranks", "runs_as_chains"]


def compare(
    store: Store, studies: Sequence[StudyRecord], fmt: str, cache: FigureCache, seed: int = 0
) -> bytes:
    """Posterior densities of the parameters the studies share, each study's final stage and
    their pool (equal numbers of samples from each; Figure 9)."""
    finals = []
    for st in studies:
        stages = [s.stage_index for s in store.stages.list(st.id) if s.status == "done"]
        if not stages:
            raise FigureError(f"study {st.id} has no finished stage")
        finals.append(stage_data(store, st, stages[-1], cache))
    shared = [n for n in finals[0].names if all(n in f.names for f in finals[1:])]
    if not shared:
        raise FigureError("the studies share no parameter")

    def make() -> bytes:
        cols = [np.array([f.names.index(n) for n in shared]) for f in finals]
        per = {
            f"{st.id}: {st.name}": f.samples[:, c]
            for st, f, c in zip(studies, finals, cols, strict=True)
        }
        n = min(len(x) for x in per.values())
        pooled = pool_samples(list(per.values()), n, seed)
        case = stored_case(studies[0].case)
        return plots.figures.render(
            plots.posterior.compare_figure(
                shared,
                per,
                pooled,
                units=dict(case.prior().units or {}),
                log_params=log_params(case),
                title="Posteriors of the compared studies and their pool (Figure 9)",
            ),
            fmt,
        )

    return cache.get_or_make(("compare", tuple(s.id for s in studies), seed, fmt), make)


def final_populations(store: Store, studies: Sequence[StudyRecord]) -> list[np.ndarray] | None:
    """Each study's samples at its last finished stage (n_i, d_i); None if one has none."""
    finals = []
    for st in studies:
        done = [s.stage_index for s in store.stages.list(st.id) if s.status == "done"]
        if not done:
            return None
        finals.append(store.samples.arrays(st.id, done[-1]).samples)
    return finals


def runs_as_chains(
    studies: Sequence[StudyRecord], finals: Sequence[np.ndarray] | None
) -> tuple[list[str], np.ndarray] | None:
    """The studies' final populations (``finals``, see :func:`final_populations`) as runs of
    one posterior: (names, chains (K, n, d)), n samples of each (the smallest population;
    subsampled as ``/pooled`` takes them, seed 0). None unless they share their parameters
    in order and hold at least 4 samples each."""
    names = study_terms(studies[0]).parameter_names
    if finals is None or any(study_terms(s).parameter_names != names for s in studies[1:]):
        return None
    n = min(len(x) for x in finals)
    if n < 4:
        return None
    return names, pool_samples(finals, n, 0).reshape(len(finals), n, -1)


def ranks(store: Store, studies: Sequence[StudyRecord], fmt: str, cache: FigureCache) -> bytes:
    """Rank plots of the studies' final populations, one run each (ArviZ's plot_rank)."""
    why = why_not_runs(studies)
    if why is not None:
        raise FigureError(f"rank plots are of runs of one calibration: {why}")
    chains = runs_as_chains(studies, final_populations(store, studies))
    if chains is None:
        raise FigureError("rank plots need studies of the same parameters (runs of one case)")

    def make() -> bytes:
        names, x = chains
        labels = [f"{s.id}: {s.name}"[:24] for s in studies]
        title = f"Rank plots of studies {', '.join(str(s.id) for s in studies)}"
        return plots.figures.render(plots.ranks.rank_figure(names, x, labels, title=title), fmt)

    return cache.get_or_make(("ranks", tuple(s.id for s in studies), fmt), make)
