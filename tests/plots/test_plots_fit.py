"""Figure 3 (measured vs simulated signals): decimation and the simulated time axis."""

from __future__ import annotations

import gzip
import io
import itertools
import re
from pathlib import Path
from xml.etree import ElementTree

import matplotlib
import numpy as np
import pytest

from scm_core.signals import load_dataset
from scm_core.simulator import RigConfig, simulate_swt
from services.plots.figures import render
from services.plots.fit import MAX_POINTS, decimated, fit_chart
from services.plots.mpl import draw

LOG = Path(__file__).resolve().parents[2] / "examples" / "wf34_s020.csv"


def test_decimated_keeps_the_envelope_and_only_samples() -> None:
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 180.0, 100_001)
    y = np.sin(t) + 0.01 * rng.standard_normal(t.size)
    y[31_337] = 5.0  # a one-sample impact (a grouser) must survive
    y[77_001] = -4.0
    td, yd = decimated(t, y)
    assert td.size <= MAX_POINTS + 2
    assert np.all(np.diff(td) > 0)  # in time order, no repeats
    idx = np.searchsorted(t, td)
    assert np.array_equal(t[idx], td) and np.array_equal(y[idx], yd)  # samples of the curve
    assert yd.max() == 5.0 and yd.min() == -4.0
    assert td[0] == t[0] and td[-1] == t[-1]
    # each bin's extremes are kept: the drawn envelope matches the curve's to the bin width
    bins = np.linspace(0.0, 180.0, 11)
    for a, b in itertools.pairwise(bins):
        sel, seld = (t >= a) & (t < b), (td >= a) & (td < b)
        assert y[sel].max() == pytest.approx(yd[seld].max(), abs=0.05)


def test_short_curves_are_drawn_as_they_are() -> None:
    t = np.arange(10.0)
    td, yd = decimated(t, t**2)
    assert np.array_equal(td, t) and np.array_equal(yd, t**2)


def test_a_short_simulation_spans_the_measured_window() -> None:
    """A 12 s simulation of a longer lab log: its averaging window is drawn over the log's
    window (not over the first seconds of the axis), with the simulated time on a top axis,
    and the figure stays light."""
    ds = load_dataset(LOG)
    lo, hi = ds.window
    sim = simulate_swt(
        rig=RigConfig(duration=12.0, dt=0.02, offset_F=4.0, offset_T=4.0, offset_z=1.0)
    )
    chart = fit_chart([ds], [sim], responses=("F", "T", "z"))
    panel = chart.panels[0]  # F
    simulated = [la for la in panel.layers if la.get("label") == "simulated (filtered)"]
    x = np.array(simulated[0]["x"])
    # the simulated window [4, 12] s maps onto the measured window [lo, hi]
    b = (hi - lo) / (12.0 - 4.0)
    assert x[-1] == pytest.approx(hi, abs=b * 0.05)
    assert x[0] == pytest.approx(lo - 4.0 * b, abs=b * 0.05)
    assert panel.x.lo <= x[0]  # the simulation's start is on the axis
    label, a, scale = panel.top  # the simulated time over the top
    assert label == "simulated time [s]" and (x[-1] - a) / scale == pytest.approx(12.0, abs=0.05)
    for p in chart.panels:
        for layer in p.layers:
            assert len(layer.get("x", ())) <= MAX_POINTS + 2
    fig = draw(chart)
    ax = fig.axes[0]
    assert any(
        getattr(child, "get_xlabel", lambda: "")() == "simulated time [s]"
        for child in ax.child_axes
    )
    buf = io.BytesIO()
    fig.savefig(buf, format="svg")
    assert buf.tell() < 400_000


def test_served_svg_paths_are_cut_to_a_tenth_of_a_point() -> None:
    """The served SVG parses, keeps every path, and no path coordinate has more than one
    decimal (0.1 pt: below a pixel); a figure of two long logs takes less than 60 KB gzipped."""
    ds = [load_dataset(LOG)] * 2
    sim = simulate_swt(
        rig=RigConfig(duration=12.0, dt=0.02, offset_F=4.0, offset_T=4.0, offset_z=1.0)
    )
    fig = draw(fit_chart(ds, [sim, sim]))
    svg = render(fig, "svg")
    root = ElementTree.fromstring(svg)
    paths = [el.get("d") for el in root.iter("{http://www.w3.org/2000/svg}path") if el.get("d")]
    assert paths
    assert not any(re.search(r"\d\.\d\d", d) for d in paths)
    raw = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(raw, format="svg")
    assert raw.getvalue().count(b"<path") == svg.count(b"<path")
    assert len(gzip.compress(svg)) < 60_000
