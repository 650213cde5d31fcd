"""The figure layer the dashboard and the CLI share: rendering to bytes, the schedule with
stages not yet done, thinning of large samples, and the cache."""

from __future__ import annotations

import threading
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from services.api.dashboard.figures import FigureCache
from services.plots.figures import render
from services.plots.posterior import pair_matrix_figure, pairs_figure
from services.plots.stages import schedule_figure, stage_trace_figure


def test_render_is_deterministic_and_checks_the_format() -> None:
    fig = schedule_figure([0, 1, 2], [0.0, 0.01, 1.0], [None, 0.3, 0.25], [500, 250, 260], 500)
    svg = render(fig, "svg")
    assert svg == render(fig, "svg")  # no creation date: the same figure, the same bytes
    root = ET.fromstring(svg)
    assert root.tag.endswith("svg")
    texts = "".join(t.text or "" for t in root.iter() if t.tag.endswith("text"))
    assert "stage j" in texts  # text kept as text
    assert render(fig, "png").startswith(b"\x89PNG")
    with pytest.raises(ValueError, match="format"):
        render(fig, "gif")


def test_schedule_of_a_stage_not_done_leaves_it_out() -> None:
    fig = schedule_figure([0, 1, 2], [0.0, 0.05, None], [None, 0.4, None])
    ax_p, ax_a = fig.axes[:2]
    assert ax_p.lines[0].get_xdata().tolist() == [1.0]  # p = 0 has no place on a log axis
    assert ax_a.lines[0].get_xdata().tolist() == [1.0]


def test_pairs_of_a_large_sample_draw_at_most_max_points() -> None:
    rng = np.random.default_rng(1)
    X = rng.normal(size=(16_000, 2))
    fig = pairs_figure(["a", "b"], X, pairs=[("a", "b")], max_points=4000)
    dots = fig.axes[0].collections[0]
    assert dots.get_offsets().shape[0] == 4000 and dots.get_rasterized()
    assert len(render(fig, "svg")) < 300_000


def test_cache_keeps_the_newest_entries() -> None:
    cache = FigureCache(max_entries=2)
    made = []
    for key in ("a", "b", "a", "c", "b"):
        cache.get_or_make(key, lambda k=key: made.append(k) or k)
    assert made == ["a", "b", "c", "b"]  # "a" reused once; "b" evicted by "c" after "a"


def test_cache_makes_a_value_once_for_concurrent_callers() -> None:
    """A figure asked for while it is being drawn (the warmer drawing, a page asking) is drawn
    once: the second caller waits and gets the first's bytes; a failed draw is retried."""
    cache = FigureCache()
    started, release, made = threading.Event(), threading.Event(), []

    def slow() -> bytes:
        made.append(1)
        started.set()
        release.wait(10)
        return b"drawn"

    got: list[bytes] = []
    first = threading.Thread(target=lambda: got.append(cache.get_or_make("k", slow)))
    first.start()
    started.wait(10)
    second = threading.Thread(target=lambda: got.append(cache.get_or_make("k", slow)))
    second.start()
    second.join(0.2)
    assert second.is_alive()  # waiting, not drawing beside the first
    release.set()
    first.join(10)
    second.join(10)
    assert got == [b"drawn", b"drawn"] and made == [1] and "k" in cache

    def broken() -> bytes:
        raise RuntimeError("no")

    with pytest.raises(RuntimeError):
        cache.get_or_make("bad", broken)
    assert cache.get_or_make("bad", lambda: b"ok") == b"ok"


def test_stage_trace_draws_each_stage_population_quantiles() -> None:
    """A population shrinking from the prior (stage 0) to the posterior: each panel's median
    line is the stage's sample median, its bands the 2.5-97.5 % and 25-75 % quantiles (numpy's),
    one panel per parameter, log axes where asked."""
    rng = np.random.default_rng(0)
    sd = (1.0, 0.5, 0.1)
    pops = [np.column_stack([rng.normal(2.0, s, 400), 10 ** rng.normal(6.0, s, 400)]) for s in sd]
    fig = stage_trace_figure(["phi", "k_phi"], [0, 1, 2], pops, log_params={"k_phi"})
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 2 and axes[1].get_yscale() == "log"
    for k, ax in enumerate(axes):
        np.testing.assert_allclose(ax.lines[0].get_ydata(), [np.median(p[:, k]) for p in pops])
        outer = ax.collections[0].get_paths()[0].vertices[:, 1]
        for p in pops:
            lo, hi = np.quantile(p[:, k], [0.025, 0.975])
            assert np.isclose(outer, lo).any() and np.isclose(outer, hi).any()
    assert render(fig, "svg").startswith(b"<?xml")


def test_pair_matrix_has_marginals_on_the_diagonal_and_pairs_below() -> None:
    """Three parameters: 6 panels (3 marginals, 3 pairs), the marginal densities integrate to
    one (scipy's kernel density), log10 where asked; the pair panels draw the samples."""
    rng = np.random.default_rng(1)
    x = np.column_stack(
        [rng.normal(30, 2, 500), 10 ** rng.normal(6, 0.3, 500), rng.normal(1, 0.1, 500)]
    )
    fig = pair_matrix_figure(["phi", "k_phi", "n"], x, ["phi", "k_phi", "n"], log_params={"k_phi"})
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 6
    diag = [ax for ax in axes if ax.lines and not ax.collections]
    assert len(diag) == 3
    for ax in diag:
        g, dens = ax.lines[0].get_data()
        assert np.trapezoid(dens, g) == pytest.approx(1.0, abs=0.02)
    means = [np.average(ax.lines[0].get_xdata(), weights=ax.lines[0].get_ydata()) for ax in diag]
    centres = sorted(float(m) for m in means)
    assert centres == pytest.approx([1.0, 6.0, 30.0], abs=0.1)  # log10 k_phi around 6
    assert "log10" in fig.axes[3].get_ylabel()  # second row: k_phi
    assert render(fig, "svg").startswith(b"<?xml")


def test_rank_figure_labels_every_run_on_every_parameter() -> None:
    """ArviZ's rank plots, one panel per parameter, each run's histogram labelled with it."""
    from services.plots.ranks import rank_figure

    chains = np.random.default_rng(2).normal(size=(3, 200, 2))
    fig = rank_figure(["phi", "n"], chains, ["1: a", "2: b", "3: c"])
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in axes] == ["phi", "n"]
    for ax in axes:
        assert [t.get_text() for t in ax.get_yticklabels()] == ["1: a", "2: b", "3: c"]
    assert ET.fromstring(render(fig, "svg")).tag.endswith("svg")
