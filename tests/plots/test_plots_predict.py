"""The predictions figure: each dataset's median and interval drawn and named in the legend."""

from __future__ import annotations

from scm_core.calibration.predict import Band, ConditionPrediction, ResponsePrediction
from services.plots.mpl import draw
from services.plots.predict import predictions_chart


def _condition(name: str, slip: float, median: float, measured: float, role: str):
    band = Band(median, median - 2.0, median + 3.0)
    resp = ResponsePrediction("F", band, band, measured)
    return ConditionPrediction(name, {}, slip, 10, 0, {"F": resp}, role)


def test_each_dataset_shows_its_median_and_interval_with_a_legend() -> None:
    datasets = [
        _condition("a", -0.5, -16.0, -17.7, "calibration"),
        _condition("b", 0.5, 1.2, 2.8, "predicted"),
    ]
    chart = predictions_chart(datasets, [], responses=("F",))
    bars = next(la for la in chart.panels[0].layers if la["kind"] == "errorbars")
    assert bars["y"] == [-16.0, 1.2] and bars["lo"] == [-18.0, -0.8] and bars["hi"] == [-13.0, 4.2]
    measured = [la for la in chart.panels[0].layers if la["kind"] == "points"]
    assert [(m["symbol"], m["y"]) for m in measured] == [("o", [-17.7]), ("s", [2.8])]
    fig = draw(chart)  # the download: matplotlib draws the same
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "predicted median, 95 % predictive interval" in labels
    assert "measured, used in the calibration" in labels and "measured, held out" in labels
    # the median is drawn as a marker at the predicted value, the bar spans the interval
    ticks = [ln for ln in ax.get_lines() if ln.get_marker() == "_" and ln.get_markersize() == 9]
    assert sorted(float(y) for ln in ticks for y in ln.get_ydata()) == [-16.0, 1.2]
    segments = [c for c in ax.collections if hasattr(c, "get_segments") and c.get_segments()]
    spans = sorted(
        (float(s[:, 1].min()), float(s[:, 1].max())) for c in segments for s in c.get_segments()
    )
    assert (-18.0, -13.0) in spans and (-0.8, 4.2) in [(round(a, 6), round(b, 6)) for a, b in spans]


def test_a_long_title_is_wrapped_inside_the_figure() -> None:
    """A cross-wheel check's title (the case and the wheel it predicts) fits the figure's width
    on the page it is saved to: nothing is cut at either edge."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    title = (
        "cmu_smooth's posterior on another wheel (R 58 mm, b 50 mm, 12 grousers of 5 mm), 200 draws"
    )
    chart = predictions_chart([_condition("a", 0.5, 1.2, 2.8, "predicted")], [], title, ("F",))
    fig = draw(chart)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    (text,) = [t for t in fig.texts if t.get_text().replace("\n", " ") == title]
    assert "\n" in text.get_text()
    box = text.get_window_extent(canvas.get_renderer())
    assert box.x0 >= 0.0 and box.x1 <= fig.bbox.width


def test_two_wheels_are_told_apart() -> None:
    """Issue 69: a joint study of two wheels tested at the same slips: each wheel's bars and
    points in a colour of its own, set apart by a small slip offset, the wheel named in the
    legend (one marker on one slip axis before)."""
    from services.plots.predict import DODGE

    smooth = {"R": 0.1475, "b": 0.12, "n_grousers": 0, "grouser_height": 0.0}
    grousered = {"R": 0.1475, "b": 0.12, "n_grousers": 12, "grouser_height": 0.012}
    datasets = []
    for slip in (-0.5, 0.5):
        for wheel in (smooth, grousered):
            c = _condition(f"{slip}", slip, 1.0, 1.5, "calibration")
            datasets.append(ConditionPrediction(c.name, wheel, slip, 10, 0, c.responses, c.role))
    chart = predictions_chart(datasets, [], responses=("F",))
    bars = [la for la in chart.panels[0].layers if la["kind"] == "errorbars"]
    assert len(bars) == 2 and bars[0]["color"] != bars[1]["color"]
    assert bars[0]["x"] == [-0.5 - DODGE / 2, 0.5 - DODGE / 2]
    assert bars[1]["x"] == [-0.5 + DODGE / 2, 0.5 + DODGE / 2]
    assert bars[0]["label"].startswith("R 147.5 mm, b 120 mm, smooth: predicted median")
    assert bars[1]["label"].startswith("R 147.5 mm, b 120 mm, 12 grousers of 12 mm: predicted")
    pts = [la for la in chart.panels[0].layers if la["kind"] == "points"]
    assert [p["color"] for p in pts] == [bars[0]["color"], bars[1]["color"]]
    fig = draw(chart)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert sum("smooth" in t for t in labels) == 2 and sum("grousers" in t for t in labels) == 2


def test_a_force_map_draws_a_line_and_band_per_slip_angle() -> None:
    """``--map``'s figure: a panel per response given, in each a line (the median, in the
    figure's unit: z in mm) and its band per slip angle against the slip, named in the first
    panel's legend."""
    from services.plots.predict import force_map_chart

    def point(slip: float, angle: float) -> ConditionPrediction:
        z = Band(0.02 + slip / 100, 0.019, 0.03)
        responses = {
            "F": ResponsePrediction("F", Band(slip, slip - 1, slip + 1), None),
            "z": ResponsePrediction("z", z, None),
        }
        return ConditionPrediction("p", {"slip_angle": angle}, slip, 4, 0, responses, "map")

    grid = [point(s, a) for s in (0.5, -0.5) for a in (0.0, 45.0)]
    chart = force_map_chart(grid, "a map")
    assert [p.y.label for p in chart.panels] == ["drawbar pull F [N]", "sinkage z [mm]"]
    lines = [la for la in chart.panels[1].layers if la["kind"] == "line"]
    assert [la["x"] for la in lines] == [[-0.5, 0.5], [-0.5, 0.5]]  # sorted by slip
    assert lines[0]["y"] == [15.0, 25.0]
    assert [la["label"] for la in chart.panels[0].layers if la["kind"] == "line"] == [
        "slip angle 0 deg",
        "slip angle 45 deg",
    ]
    assert sum(la["kind"] == "band" for la in chart.panels[0].layers) == 2
    draw(chart)
