"""Issue 69: posterior figures a reader does not have to guess at: no exponent beside a unit
(J in mm/s, lengths in mm), and the one legend shows every kind of line drawn."""

from __future__ import annotations

import numpy as np
import pytest

from services.plots.mpl import draw
from services.plots.posterior import label, pairs_chart, prior_posterior_chart

NAMES = ["k_phi", "n", "phi", "J"]


def _samples(n: int = 400) -> np.ndarray:
    rng = np.random.default_rng(3)
    return np.column_stack(
        [
            10 ** rng.uniform(6.5, 7.5, n),
            rng.normal(1.1, 0.1, n),
            rng.normal(29.0, 1.5, n),
            rng.normal(0.0045, 0.0007, n),  # m/s: drawn as mm/s
        ]
    )


def test_j_is_drawn_in_mm_per_s_without_an_exponent() -> None:
    post = _samples()
    chart = pairs_chart(NAMES, post, pairs=[("phi", "J")], reference={"phi": 30.0, "J": 0.004})
    (panel,) = chart.panels
    assert panel.y.label == "J [mm/s]" and label("J") == "J [mm/s]"
    dots = next(la for la in panel.layers if la["kind"] == "points")
    assert np.allclose(dots["y"], post[:, 3] * 1000.0, rtol=1e-4)  # charts keep 5 digits
    ref = next(la for la in panel.layers if la["kind"] == "marker")
    assert ref["y"] == pytest.approx(4.0)  # the bevameter J, in mm/s too
    fig = draw(chart)
    fig.canvas.draw()  # the tick formatter decides its offset text when drawn
    ax = fig.axes[0]
    assert ax.yaxis.get_offset_text().get_text() == ""
    assert label("sigma_z") == "sigma_z [mm]" and label("R") == "R [mm]"
    assert label("J", {"J": "m/s"}) == "J [mm/s]" and label("phi") == "phi [deg]"


def test_the_one_legend_shows_the_bevameter_lines() -> None:
    """The bevameter value is known for n and phi only: the legend goes on the first panel
    that has every kind of line (n's), not on k_phi's, which has no dotted line."""
    post = _samples()
    prior = _samples() * np.array([1.0, 1.3, 1.2, 1.5])
    chart = prior_posterior_chart(
        NAMES,
        prior,
        post,
        map_sample=post[0],
        reference={"n": 1.1, "phi": 30.0},
        log_params=("k_phi",),
    )
    with_legend = [p for p in chart.panels if p.legend]
    assert len(with_legend) == 1
    shown = {la.get("label") for la in with_legend[0].layers}
    assert {"prior", "posterior", "MAP", "bevameter"} <= shown
    assert with_legend[0] is chart.panels[1]  # n: the first with a bevameter line
    j = chart.panels[3]
    assert j.x.label == "J [mm/s]"
    map_line = next(la for la in j.layers if la.get("label") == "MAP")
    assert map_line["x"] == pytest.approx(post[0, 3] * 1000.0, rel=1e-4)
    fig = draw(chart)
    assert sum(ax.get_legend() is not None for ax in fig.axes) == 1
