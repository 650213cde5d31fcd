"""Figure 3 (measured vs simulated signals): decimation and the shared travel axis."""

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


def test_measured_and_simulated_share_the_carriage_travel_axis() -> None:
    """Issue 69: a 12 s simulation of a 180 s lab log is drawn on the carriage's travel
    x = v t, as the log is (not stretched over the log's window on a second time axis): its
    last point at v x 12 s, the log's at v x 180 s; one legend (the first panel's, with no
    values in it), each panel's means stated with units; the sinkage axis spans the steady
    signals, not 0, so that a millimetre's misfit shows; the figure stays light."""
    ds = load_dataset(LOG)
    lo, _ = ds.window
    sim = simulate_swt(
        rig=RigConfig(duration=12.0, dt=0.02, offset_F=4.0, offset_T=4.0, offset_z=1.0)
    )
    v = ds.conditions.carriage_speed or sim.rig.carriage_speed
    chart = fit_chart([ds], [sim], responses=("F", "T", "z"))
    for p, offset in zip(chart.panels, (4.0, 4.0, 1.0), strict=True):
        assert p.top is None
        simulated = [la for la in p.layers if la.get("label") == "simulated (filtered)"]
        measured = [la for la in p.layers if la.get("label") == "measured (filtered)"]
        assert simulated[0]["x"][-1] == pytest.approx(v * 12.0, rel=1e-9)
        assert measured[0]["x"][-1] == pytest.approx(v * float(ds.series.t[-1]), rel=1e-9)
        windows = [la for la in p.layers if la["kind"] == "vspan"]
        assert windows[0]["x0"] == pytest.approx(v * lo)
        assert windows[1]["x0"] == pytest.approx(v * offset)
        assert (p.x.lo, p.x.hi) == (0.0, pytest.approx(v * float(ds.series.t[-1])))
        for layer in p.layers:
            assert len(layer.get("x", ())) <= MAX_POINTS + 2
    assert chart.panels[-1].x.label == "carriage travel x [m]"
    assert [p.legend is not None for p in chart.panels] == [True, False, False]
    labels = {la.get("label") for p in chart.panels for la in p.layers} - {None}
    assert labels == {
        "measured (filtered)",
        "measured window",
        "measured mean",
        "simulated (filtered)",
        "simulated window",
        "simulated mean",
    }
    notes = [la["text"] for p in chart.panels for la in p.layers if la["kind"] == "text"]
    assert notes[0].startswith("measured ") and notes[0].count(" N") == 2
    assert notes[1].count(" N m") == 2 and notes[2].count(" mm") == 2
    z = chart.panels[2]
    z_mean = ds.responses["z"].mean * 1000.0
    assert z.y.lo > 0.5 * z_mean and z.y.hi - z.y.lo < 0.5 * z_mean  # the steady part, not 0
    fig = draw(chart)
    assert sum(ax.get_legend() is not None for ax in fig.axes) == 1
    assert {ax.get_xlabel() for ax in fig.axes} == {"", "carriage travel x [m]"}
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
