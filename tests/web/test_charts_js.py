"""The dashboard's chart renderer (``static/charts.js``) in a real headless Chromium (Debian's
``/usr/bin/chromium`` driven by Playwright, as in test_dashboard_browser.py; no browser
download), drawing specs built with :mod:`services.plots.chart`'s own builders.

What is asserted comes from the specs: their layer kinds, axis ranges and data points; the
page is a bare HTML page with the script inlined, no server.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from services.plots.chart import (
    Axis,
    Chart,
    Panel,
    band,
    bars,
    contours,
    errorbars,
    hline,
    hspan,
    line,
    marker,
    points,
    segment,
    text,
    vline,
    vspan,
)

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = (ROOT / "services/api/dashboard/static/charts.js").read_text()
CHROMIUM = os.environ.get("SCM_CALIB_TEST_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking"]  # as the dashboard's
ARGS += ["--disable-component-update", "--disable-sync", "--no-first-run"]
KINDS = ("line", "band", "bars", "points", "contours", "vline", "hline", "segment")
KINDS += ("vspan", "hspan", "marker", "text")
LINE_X, LINE_Y = [1.0, 2.0, 3.0, 4.0, 5.0], [2.0, 4.0, 3.0, 5.0, 1.0]
LABEL = "a <b>line</b>"


def full_chart() -> Chart:
    """Every kind of layer, linear/log/integer axes, a top axis, a gap and an empty cell."""
    t = np.linspace(0, 2 * np.pi, 40)
    first = Panel(Axis("t [s]"), Axis("value"), legend="best").add(
        line(LINE_X, LINE_Y, marker="o", label=LABEL),
        line([1, 2, None, 4, 5], [1, 1.5, None, 2, 2.5], dash="dashed", color="green"),
        band(LINE_X, [0.5] * 5, [1.5] * 5, label="band"),
        vline(2.5, dash="dotted", label="now"),
        hline(4.5),
        segment(1.5, 3.5, 0.8, label="mean"),
        vspan(4.2, 4.8, label="window"),
        hspan(0.2, 0.4),
        marker(3.5, 3.5, label="truth"),
        text("note <i>not markup</i>", 0.02, 0.95),
    )
    stages = Panel(Axis("stage", integer=True), Axis("ESS"), legend=None).add(
        line([0, 1, 2, 3], [10, 30, 20, 40], marker="s"),
        bars([0, 1, 2, 3], [5, 7, 6], fill=False, label="hist"),
    )
    rng = np.random.default_rng(1)
    logs = Panel(
        Axis("N", scale="log"),
        Axis("rate", scale="log"),
        title="log <axes>",
        top=("weeks", 0.0, 1000.0),
        legend="upper left",
    ).add(points(10 ** rng.uniform(4, 7, 300), 10 ** rng.uniform(0, 1.7, 300), label="draws"))
    levels = [(0.5 * k, [(np.cos(t) * k, np.sin(t) * k)]) for k in (1, 2, 3)]
    shape = Panel(Axis("a"), Axis("b", tick_labels=False), title="contours").add(
        contours(levels, label="density"), bars([-3, -1, 1, 3], [1, 2, 1], opacity=0.3)
    )
    filled = Panel(Axis("x"), Axis("count", scale="log")).add(
        bars([0, 1, 2, 3, 4], [3, 30, 300, 3000], label="filled")
    )
    return Chart("<b>all</b> layers", [first, stages, logs, shape, None, filled], 3, (12, 7))


@pytest.fixture(scope="module")
def browser():
    from playwright.sync_api import sync_playwright

    if not Path(CHROMIUM).exists():
        pytest.fail(f"Chromium is required at {CHROMIUM} (apt-get install chromium)", pytrace=False)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        yield b
        b.close()


def open_page(browser, width: int = 1200):
    ctx = browser.new_context(viewport={"width": width, "height": 900})
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.set_content('<!doctype html><body style="margin:8px"><div id="c"></div></body>')
    page.add_script_tag(content=SCRIPT)
    return ctx, page, errors


@pytest.fixture
def page(browser):
    ctx, page, errors = open_page(browser)
    yield page
    assert errors == []
    ctx.close()


def render(page, chart: Chart) -> None:
    page.evaluate(
        "s => { window.h = ScmCharts.render(document.getElementById('c'), JSON.parse(s)); }",
        json.dumps(chart.to_json()),
    )
    page.wait_for_selector("svg.chart[data-ready='1']")


def panel(page, i: int) -> str:
    return f"svg.chart g.chart-panel[data-panel='{i}']"


def lims(page, i: int, which: str = "x") -> list[float]:
    value = page.get_attribute(panel(page, i), f"data-{which}lim")
    return [float(v) for v in value.split(",")]


def to_px(page, i: int, x: float, y: float) -> tuple[float, float]:
    """Where data (x, y) is on screen (linear axes), from the panel's plot area and limits."""
    box = page.locator(panel(page, i) + " .chart-hit").bounding_box()
    (x0, x1), (y0, y1) = lims(page, i, "x"), lims(page, i, "y")
    fx, fy = (x - x0) / (x1 - x0), (y - y0) / (y1 - y0)
    return box["x"] + fx * box["width"], box["y"] + (1 - fy) * box["height"]


def drag(page, a: tuple[float, float], b: tuple[float, float]) -> None:
    page.mouse.move(*a)
    page.mouse.down()
    page.mouse.move(*b, steps=5)
    page.mouse.up()


def tick_texts(page, i: int, axis: str) -> list[str]:
    return page.locator(panel(page, i) + f" .chart-ticks-{axis} text").all_text_contents()


def test_every_layer_kind_and_axis(page) -> None:
    render(page, full_chart())
    svg = page.locator("svg.chart")
    assert svg.get_attribute("role") == "img"
    assert svg.get_attribute("aria-label") == "<b>all</b> layers"
    assert page.locator("svg.chart g.chart-panel").count() == 5  # the null panel drawn as nothing
    for kind in KINDS:
        assert page.locator(f"svg.chart .layer.layer-{kind}").count() >= 1, kind
    assert page.locator(panel(page, 0) + " .chart-legend").count() == 1
    assert page.locator(panel(page, 1) + " .chart-legend").count() == 0  # legend=None
    # the line with a null in the middle is drawn in two pieces
    assert page.locator(panel(page, 0) + " g.layer-line").nth(1).locator("path").count() == 2
    # log axes: decades over 3 decades of x; 1, 2, 5 steps under 2 decades of y
    xs = tick_texts(page, 2, "x")
    assert all(re.fullmatch(r"1e\d", s) for s in xs), xs
    assert {float(s) for s in xs} == {1e4, 1e5, 1e6, 1e7}
    ys = [float(s) for s in tick_texts(page, 2, "y")]
    assert {1, 2, 5, 10, 20} <= set(ys) and all(v in (1, 2, 5, 10, 20, 50) for v in ys), ys
    # the top axis: (x - 0) / 1000 over x in 1e4..1e7
    top = [float(s) for s in tick_texts(page, 2, "top")]
    assert len(top) >= 2 and min(top) >= 0 and max(top) <= 1.2e4
    # integer axis 0..3: integer labels only
    ints = tick_texts(page, 1, "x")
    assert len(ints) >= 3 and all(re.fullmatch(r"-?\d+", s) for s in ints), ints
    assert tick_texts(page, 3, "y") == []  # tick_labels=False
    # limits fitted with 4 % padding; bars on a linear axis start at 0
    x0, x1 = lims(page, 0, "x")
    assert x0 == pytest.approx(1 - 0.16, abs=1e-6) and x1 == pytest.approx(5 + 0.16, abs=1e-6)
    assert lims(page, 1, "y")[0] == 0


def test_labels_are_text_not_markup(page) -> None:
    render(page, full_chart())
    assert page.locator("svg.chart b, svg.chart i").count() == 0
    assert LABEL in page.locator(panel(page, 0) + " .chart-legend").text_content()
    assert "log <axes>" in page.locator(panel(page, 2)).text_content()
    assert "<b>all</b> layers" in page.locator("svg.chart").text_content()


def test_hover_reads_the_nearest_point(page) -> None:
    render(page, full_chart())
    x, y = to_px(page, 0, 3.0, 3.0)
    page.mouse.move(x + 3, y - 2)
    readout = page.locator("#c .chart-readout[role=status]")
    first, second = readout.text_content().split("\n")
    m = re.fullmatch(r"t \[s\] = (\S+), value = (\S+)", first)
    assert m and (float(m[1]), float(m[2])) == pytest.approx((3, 3), abs=0.2)
    assert second == f"{LABEL}: x = 3, y = 3"
    page.mouse.move(5, 5)  # outside every panel
    assert readout.is_hidden()


BAR_X, BAR_Y = [1.0, 2.0, 3.0, 4.0], [2.0, 2.5, None, 1.5]
BAR_LO, BAR_HI = [1.2, 0.5, 1.0, 1.1], [2.6, 3.8, 2.0, 1.9]  # the third bar's null y: skipped
SQUARE_X, SQUARE_Y = [1.5, 2.5, 3.5], [1.8, 2.2, 2.4]


def bars_chart() -> Chart:
    """Error bars (medians and their intervals) over square points."""
    return Chart(
        "intervals",
        [
            Panel(Axis("x"), Axis("y"), legend="upper right").add(
                points(SQUARE_X, SQUARE_Y, size=3, opacity=1, label="runs", symbol="s"),
                errorbars(BAR_X, BAR_Y, BAR_LO, BAR_HI, color="red", label="median, 95 %"),
            )
        ],
    )


def path_points(page, selector: str) -> list[tuple[float, float]]:
    """Screen points sampled along a drawn path, every 0.25 px of its length."""
    js = """sel => {
      const path = document.querySelector(sel), m = path.getScreenCTM(), n = path.getTotalLength();
      const at = (s) => path.getPointAtLength(Math.min(s, n)).matrixTransform(m);
      return Array.from({ length: Math.ceil(n / 0.25) + 1 }, (_, k) => at(k * 0.25))
        .map((p) => [p.x, p.y]);
    }"""
    return [tuple(p) for p in page.evaluate(js, selector)]


def test_errorbars_and_square_points(page) -> None:
    render(page, bars_chart())
    bar = panel(page, 0) + " path.layer.layer-errorbars"
    assert page.locator(bar).count() == 1
    drawn = path_points(page, bar)
    for i in (0, 1, 3):  # each drawn bar spans lo..hi at its x
        x, top = to_px(page, 0, BAR_X[i], BAR_HI[i])
        bottom = to_px(page, 0, BAR_X[i], BAR_LO[i])[1]
        ys = sorted(py for px, py in drawn if abs(px - x) < 1)
        assert (ys[0], ys[-1]) == pytest.approx((top, bottom), abs=1.0), i
        assert max(np.diff(ys)) < 1, i  # one unbroken vertical line
    x = to_px(page, 0, BAR_X[2], 0)[0]
    assert not [p for p in drawn if abs(p[0] - x) < 8]  # nothing at the bar with a null y
    # the y limits: the lowest lo and highest hi with 4 % padding (the points lie inside)
    y0, y1 = lims(page, 0, "y")
    lo, hi = min(BAR_LO), max(BAR_HI)
    assert [y0, y1] == pytest.approx([lo - 0.04 * (hi - lo), hi + 0.04 * (hi - lo)], abs=1e-6)
    # the square points: one path, no arcs, spanning the points' extent and their size
    squares = page.locator(panel(page, 0) + " path.layer.layer-points")
    assert squares.count() == 1
    d = squares.get_attribute("d")
    assert d and not re.search("[aA]", d), d
    box = squares.bounding_box()
    left, low = to_px(page, 0, min(SQUARE_X), min(SQUARE_Y))
    right, high = to_px(page, 0, max(SQUARE_X), max(SQUARE_Y))
    assert box["x"] == pytest.approx(left - 3, abs=1)  # squares of side 2 * size = 6 px
    assert box["width"] == pytest.approx(right - left + 6, abs=1)
    assert box["y"] == pytest.approx(high - 3, abs=1)
    assert box["height"] == pytest.approx(low - high + 6, abs=1)
    legend = page.locator(panel(page, 0) + " .chart-legend").text_content()
    assert "runs" in legend and "median, 95 %" in legend
    # hovering at a bar's (x, y) reads out its y, lo and hi
    page.mouse.move(*to_px(page, 0, BAR_X[1], BAR_Y[1]))
    readout = page.locator("#c .chart-readout[role=status]")
    assert readout.text_content().split("\n")[1] == "median, 95 %: x = 2, y = 2.5 [0.5 … 3.8]"


def test_drag_zooms_and_double_click_resets(page) -> None:
    render(page, full_chart())
    (x0, x1), (y0, y1), other = lims(page, 0, "x"), lims(page, 0, "y"), lims(page, 1, "x")
    qx = [x0 + (x1 - x0) / 4, x0 + 3 * (x1 - x0) / 4]  # the middle half of the panel
    qy = [y0 + (y1 - y0) / 4, y0 + 3 * (y1 - y0) / 4]
    drag(page, to_px(page, 0, qx[0], qy[1]), to_px(page, 0, qx[1], qy[0]))
    zx, zy = lims(page, 0, "x"), lims(page, 0, "y")
    assert zx == pytest.approx(qx, abs=0.02 * (x1 - x0))
    assert zy == pytest.approx(qy, abs=0.02 * (y1 - y0))
    assert page.locator(panel(page, 0) + " .chart-reset").count() == 1
    assert lims(page, 1, "x") == other  # the other panels keep theirs
    # a resize draws again and keeps the zoom
    page.evaluate("document.getElementById('c').style.width = '700px'")
    page.wait_for_function("document.querySelector('svg.chart').getAttribute('width') === '700'")
    assert lims(page, 0, "x") == zx
    # a short drag does not zoom; a double-click inside the panel resets it
    x, y = to_px(page, 0, (zx[0] + zx[1]) / 2, (zy[0] + zy[1]) / 2)
    drag(page, (x, y), (x + 4, y + 4))
    assert lims(page, 0, "x") == zx
    page.mouse.dblclick(x, y)
    assert lims(page, 0, "x") == [x0, x1] and lims(page, 0, "y") == [y0, y1]
    assert page.locator(panel(page, 0) + " .chart-reset").count() == 0
    # handle.reset() resets every panel
    drag(page, to_px(page, 0, qx[0], qy[1]), to_px(page, 0, qx[1], qy[0]))
    assert lims(page, 0, "x") != [x0, x1]
    page.evaluate("window.h.reset()")
    assert lims(page, 0, "x") == [x0, x1]


def test_phone_width_stacks_panels(browser) -> None:
    ctx, page, errors = open_page(browser, width=400)
    render(page, full_chart())
    assert page.locator("svg.chart").bounding_box()["width"] <= 400
    assert page.evaluate("document.documentElement.scrollWidth") <= 400
    boxes = [g.bounding_box() for g in page.locator("svg.chart g.chart-panel").all()]
    assert len(boxes) == 5
    assert max(b["x"] for b in boxes) - min(b["x"] for b in boxes) < 20  # one column
    assert all(b["y"] > a["y"] + 100 for a, b in itertools.pairwise(boxes))  # one below another
    assert errors == []
    ctx.close()


def test_a_chart_of_columns_reflows_column_by_column(browser) -> None:
    """Fig. 3 has a column per dataset: on a phone its panels stack a dataset at a time
    (reflow "columns"); other charts stack row by row."""
    ctx, page, errors = open_page(browser, width=400)
    for reflow, want in (("columns", [0, 2, 4, 1, 3, 5]), ("rows", [0, 1, 2, 3, 4, 5])):
        panels = [Panel(Axis(f"x{k}"), Axis("y")).add(line([0, 1], [k, k + 1])) for k in range(6)]
        render(page, Chart("grid", panels, columns=2, size=(10.0, 7.0), reflow=reflow))
        drawn = page.locator("svg.chart g.chart-panel").all()
        order = sorted(drawn, key=lambda g: g.bounding_box()["y"])
        assert [int(g.get_attribute("data-panel")) for g in order] == want, reflow
    assert errors == []
    ctx.close()


def test_a_kept_grid_scrolls_in_its_box_on_a_phone(browser) -> None:
    """A pair matrix keeps its rows and columns (reflow "none"): at 400 px its four columns
    stay side by side, the chart scrolls sideways in its own box and the page does not."""
    ctx, page, errors = open_page(browser, width=400)
    panels = [
        None if k > i else Panel(Axis("x"), Axis("y")).add(line([0, 1], [i, k]))
        for i in range(4)
        for k in range(4)
    ]
    render(page, Chart("matrix", panels, columns=4, size=(8.6, 8.2), reflow="none"))
    xs = sorted({round(g.bounding_box()["x"]) for g in page.locator("g.chart-panel").all()})
    assert len(xs) == 4  # four columns
    box = page.evaluate(
        "(() => { const c = document.getElementById('c');"
        " return [c.scrollWidth, c.clientWidth]; })()"
    )
    assert box[0] > box[1]  # wider than its box: it scrolls there
    assert page.evaluate("document.documentElement.scrollWidth") <= 400
    assert errors == []
    ctx.close()


def test_render_time_of_a_big_spec(page) -> None:
    rng = np.random.default_rng(2)
    x = np.linspace(0, 10, 1200)
    panels = [Panel(Axis("x"), Axis("y")).add(line(x, np.sin(x * k))) for k in (1, 2, 3, 4)]
    panels.append(Panel(Axis("a"), Axis("b")).add(points(*rng.normal(size=(2, 5000)))))
    panels.append(Panel(Axis("x"), Axis("n")).add(bars(np.arange(41), rng.integers(1, 50, 40))))
    spec = json.dumps(Chart("big", panels, 3, (12, 6)).to_json())
    times = page.evaluate(
        """s => {
          const el = document.getElementById('c'), spec = JSON.parse(s), out = [];
          for (let k = 0; k < 6; k++) {
            const t0 = performance.now();
            ScmCharts.render(el, spec);
            el.querySelector('svg').getBoundingClientRect();  // with the layout it causes
            out.push(performance.now() - t0);
          }
          return out;
        }""",
        spec,
    )
    median = sorted(times[1:])[len(times[1:]) // 2]
    print(f"render of 6 panels, 5000 points: first {times[0]:.1f} ms, median {median:.1f} ms")
    assert page.locator("svg.chart g.chart-panel").count() == 6
    assert median < 200 and math.isfinite(times[0])
