"""The axes geometry an SVG figure carries (``<metadata id="axes">``, the dashboard's hover
readout): mapped as the page maps it, a point of the image gives the data coordinates that
matplotlib's own transform put there, on linear and log axes, after constrained layout."""

from __future__ import annotations

import json
import math
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from services.plots.figures import render


def _along(f: float, lim: list[float], scale: str) -> float:
    """The page's mapping (dashboard.js ``along``)."""
    if scale == "log":
        lo, hi = math.log10(lim[0]), math.log10(lim[1])
        return 10 ** (lo + f * (hi - lo))
    return lim[0] + f * (lim[1] - lim[0])


def test_a_point_of_the_image_maps_back_to_the_data_that_matplotlib_drew_there() -> None:
    fig, (lin, log) = plt.subplots(1, 2, figsize=(7, 3), layout="constrained")
    lin.plot([20.0, 35.0], [0.9, 1.3])
    lin.set_xlabel("phi [deg]")
    log.semilogy([0.0, 1.0], [1e2, 1e6])
    twin = lin.twiny()  # a twin of the same box is left out: the first axes reads out
    twin.set_xlim(0.0, 5.0)
    svg = render(fig, "svg")
    axes = json.loads(re.search(rb'<metadata id="axes">([^<]*)</metadata>', svg).group(1))
    assert len(axes) == 2 and axes[0]["xlabel"] == "phi [deg]"
    assert [a["yscale"] for a in axes] == ["linear", "log"]
    width, height = fig.canvas.get_width_height()
    for ax, meta, points in (
        (lin, axes[0], [(22.0, 1.0), (33.0, 1.25)]),
        (log, axes[1], [(0.3, 3e2), (0.8, 2e5)]),
    ):
        left, top, right, bottom = meta["box"]
        for x, y in points:
            px, py = ax.transData.transform((x, y))  # display pixels from the bottom left
            fx, fy = px / width, 1.0 - py / height  # fractions of the image from its top left
            gx = _along((fx - left) / (right - left), meta["x"], meta["xscale"])
            gy = _along((bottom - fy) / (bottom - top), meta["y"], meta["yscale"])
            # limits are kept to 6 significant digits: a few parts per million of the span
            assert math.isclose(
                gx, x, rel_tol=1e-4, abs_tol=1e-4 * abs(meta["x"][1] - meta["x"][0])
            )
            if meta["yscale"] == "log":
                assert math.isclose(math.log10(gy), math.log10(y), abs_tol=1e-4)
            else:
                assert math.isclose(gy, y, abs_tol=1e-4 * abs(meta["y"][1] - meta["y"][0]))
    plt.close(fig)


def test_the_figure_stays_the_same_bytes_and_valid_svg() -> None:
    import xml.etree.ElementTree as ET

    def draw() -> bytes:
        fig, ax = plt.subplots(layout="constrained")
        ax.plot([0, 1], [0, 1])
        ax.set_xlabel("a <b> & c")
        try:
            return render(fig, "svg")
        finally:
            plt.close(fig)

    a, b = draw(), draw()
    assert a == b  # no date, fixed ids: the same figure, the same bytes
    ET.fromstring(a)
    meta = re.search(rb'<metadata id="axes">([^<]*)</metadata>', a).group(1)
    assert json.loads(meta)[0]["xlabel"] == "a <b> & c"
