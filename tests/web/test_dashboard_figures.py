"""The figure layer the dashboard and the CLI share: the stage figures' charts (what they show,
checked against numpy's and scipy's numbers), drawing them with matplotlib and rendering to
bytes, the schedule with stages not yet done, thinning of large samples, and the cache."""

from __future__ import annotations

import json
import threading
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from services.api.dashboard.study_figures import FigureCache
from services.plots.figures import render
from services.plots.mpl import draw
from services.plots.posterior import pair_matrix_chart, pairs_chart
from services.plots.stages import schedule_chart, stage_trace_chart


def test_render_is_deterministic_and_checks_the_format() -> None:
    fig = draw(schedule_chart([0, 1, 2], [0.0, 0.01, 1.0], [None, 0.3, 0.25], [500, 250, 260], 500))
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
    chart = schedule_chart([0, 1, 2], [0.0, 0.05, None], [None, 0.4, None])
    exponent, rates = chart.panels
    assert exponent.layers[0]["x"] == [1.0]  # p = 0 has no place on a log axis
    assert exponent.y.scale == "log" and rates.layers[0]["x"] == [1.0]
    ax_p, ax_a = draw(chart).axes[:2]  # matplotlib draws what the chart holds
    assert ax_p.lines[0].get_xdata().tolist() == [1.0] and ax_p.get_yscale() == "log"
    assert ax_a.lines[0].get_xdata().tolist() == [1.0]


def test_pairs_of_a_large_sample_draw_at_most_max_points() -> None:
    rng = np.random.default_rng(1)
    X = rng.normal(size=(16_000, 2))
    chart = pairs_chart(["a", "b"], X, pairs=[("a", "b")], max_points=4000)
    dots = chart.panels[0].layers[0]
    assert dots["kind"] == "points" and len(dots["x"]) == 4000
    assert len(json.dumps(chart.to_json())) < 150_000  # what the page fetches
    fig = draw(chart)
    drawn = fig.axes[0].collections[0]
    assert drawn.get_offsets().shape[0] == 4000 and drawn.get_rasterized()
    assert len(render(fig, "svg")) < 300_000


def test_pairs_contours_enclose_the_gaussians_mass() -> None:
    """Kernel-density contours of a standard bivariate normal sample are closed curves around
    the mean, and the one at a fraction f of the density's maximum lies near the circle of
    radius sqrt(-2 ln f (1 + h^2)): the normal's own, widened by the kernel (bandwidth h), to
    the sampling error of 3000 points."""
    X = np.random.default_rng(3).normal(size=(3000, 2))
    chart = pairs_chart(["a", "b"], X, pairs=[("a", "b")])
    levels = next(la for la in chart.panels[0].layers if la["kind"] == "contours")["levels"]
    assert len(levels) == 8
    peak = levels[-1]["value"] / 0.95
    for level in levels[1:-1]:
        f = level["value"] / peak
        # the estimate is the normal convolved with the kernel (Scott's factor h = n^(-1/6)):
        # N(0, (1 + h^2) I)
        radius = np.sqrt(-2.0 * np.log(f) * (1.0 + 3000 ** (-1 / 3)))
        for path in level["paths"]:
            x, y = np.array(path["x"]), np.array(path["y"])
            assert (x[0], y[0]) == pytest.approx((x[-1], y[-1]))  # closed
            r = np.hypot(x, y)
            assert np.median(r) == pytest.approx(radius, rel=0.06)


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
    chart = stage_trace_chart(["phi", "k_phi"], [0, 1, 2], pops, log_params={"k_phi"})
    assert len(chart.panels) == 2 and chart.panels[1].y.scale == "log"
    for k, panel in enumerate(chart.panels):
        outer, inner, median = panel.layers
        np.testing.assert_allclose(median["y"], [np.median(p[:, k]) for p in pops], rtol=1e-4)
        for q, layer in ((0.025, outer), (0.25, inner)):
            want = [np.quantile(p[:, k], [q, 1 - q]) for p in pops]
            np.testing.assert_allclose(layer["lo"], [w[0] for w in want], rtol=1e-4)
            np.testing.assert_allclose(layer["hi"], [w[1] for w in want], rtol=1e-4)
    fig = draw(chart)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 2 and axes[1].get_yscale() == "log"
    assert render(fig, "svg").startswith(b"<?xml")


def test_pair_matrix_has_marginals_on_the_diagonal_and_pairs_below() -> None:
    """Three parameters: 6 panels (3 marginals, 3 pairs), the marginal densities integrate to
    one (scipy's kernel density), log10 where asked; the pair panels draw the samples."""
    rng = np.random.default_rng(1)
    x = np.column_stack(
        [rng.normal(30, 2, 500), 10 ** rng.normal(6, 0.3, 500), rng.normal(1, 0.1, 500)]
    )
    chart = pair_matrix_chart(["phi", "k_phi", "n"], x, ["phi", "k_phi", "n"], log_params={"k_phi"})
    cells = chart.panels
    assert len(cells) == 9 and [c is None for c in cells].count(True) == 3  # above the diagonal
    diag = [cells[4 * i] for i in range(3)]
    centres = []
    for panel in diag:
        density = next(la for la in panel.layers if la["kind"] == "line")
        g, dens = np.array(density["x"]), np.array(density["y"])
        assert np.trapezoid(dens, g) == pytest.approx(1.0, abs=0.02)
        centres.append(float(np.average(g, weights=dens)))
    assert sorted(centres) == pytest.approx([1.0, 6.0, 30.0], abs=0.1)  # log10 k_phi around 6
    assert "log10" in cells[3].y.label  # second row: k_phi
    fig = draw(chart)
    assert len([ax for ax in fig.axes if ax.get_visible()]) == 6
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
