"""A steered study's figures against slip (issue 70): a column of panels per slip angle, F and
Fy with their 95 % bands and the measured points of that angle; a straight study's as before.

The measured values are rows of ``examples/cmu_steering/smooth/by_condition.csv`` (the CMU
smooth wheel at 0 and 30 deg, locked, at zero slip and at slip 0.9); the predictions are
bands about them."""

from __future__ import annotations

from itertools import pairwise

import pytest
from steering_fixtures import cmu_name, cmu_rows, cmu_summary

from scm_core.calibration.predict import Band, ConditionPrediction, ResponsePrediction
from scm_core.signals import SWTDataset, load_summary
from scm_core.simulator import RigConfig, simulate_swt
from services.plots.angles import angle_of, by_slip_angle, share_y, steered
from services.plots.chart import Axis, Panel, line
from services.plots.fit import dataset_angle, fits_against_slip, plot_slip_fit, slip_fit_chart
from services.plots.mpl import draw
from services.plots.predict import plot_predictions, predictions_chart, slip_angle_of

WHEEL = {"R": 0.058, "b": 0.05, "n_grousers": 0, "grouser_height": 0.0}
FAST = {"duration": 6.0, "dt": 0.04, "dx": 0.01, "offset_F": 3.0, "offset_T": 3.0, "offset_z": 3.0}
COLUMNS = {"F": "drawbar_pull_N_mean", "Fy": "lateral_force_N_mean", "z": "sinkage_m_mean"}


def _predictions(angles: tuple[float, ...], straight: bool = False) -> list[ConditionPrediction]:
    """A prediction per row: each response's band about its measured mean (a straight study
    gives no slip angle and predicts no Fy)."""
    out = []
    for r in cmu_rows(angles):
        keys = ("F", "z") if straight else ("F", "Fy", "z")
        responses = {}
        for k in keys:
            m = r[COLUMNS[k]]
            spread = 0.1 * abs(m) + (0.002 if k == "z" else 1.0)
            responses[k] = ResponsePrediction(
                k, Band(m, m - spread, m + spread), Band(m, m - 2 * spread, m + 2 * spread), m
            )
        conditions = {**WHEEL, "W": r["normal_load_N_mean"]}
        if not straight:
            conditions["slip_angle"] = r["slip_angle_deg"]
        name = f"{r['slip_angle_deg']:g} deg, {r['vry_cmd_mmps']:g} mm/s"
        out.append(
            ConditionPrediction(
                name, conditions, r["slip_lab_mean"], 8, 0, responses, "calibration"
            )
        )
    return out


def test_grouping_by_slip_angle_orders_the_angles_and_keeps_each_groups_order() -> None:
    preds = _predictions((0.0, 30.0, 90.0))
    shuffled = [preds[7], preds[0], preds[4], preds[1], preds[8]]
    groups = by_slip_angle(shuffled, slip_angle_of)
    assert [a for a, _ in groups] == [0.0, 30.0, 90.0]
    assert [[c.name for c in g] for _, g in groups] == [
        [preds[0].name, preds[1].name],
        [preds[4].name],
        [preds[7].name, preds[8].name],
    ]
    assert angle_of({}) == 0.0 and angle_of({"slip_angle": None}) == 0.0
    assert angle_of({"slip_angle": 60}) == 60.0
    assert not steered(_predictions((0.0,), straight=True), slip_angle_of)
    assert steered(preds, slip_angle_of) and by_slip_angle([], slip_angle_of) == []


def test_share_y_spans_every_panels_values() -> None:
    a = Panel(Axis(), Axis()).add(line([0, 1], [1.0, 2.0]))
    b = Panel(Axis(), Axis()).add(line([0, 1], [-9.0, None]))
    share_y([a, b])
    assert a.y == b.y and a.y.lo < -9.0 and a.y.hi > 2.0


def _ordered(*series: list[float]) -> bool:
    """Whether the series hold lo <= ... <= hi at every point."""
    return all(all(a <= b for a, b in pairwise(col)) for col in zip(*series, strict=True))


def _layers(panel, kind: str) -> list[dict]:
    return [la for la in panel.layers if la["kind"] == kind]


def test_a_steered_predictions_chart_has_a_column_per_angle_with_fy() -> None:
    datasets = _predictions((0.0, 30.0, 60.0))
    sweep = [
        ConditionPrediction(
            f"sweep {s}", {**WHEEL, "slip_angle": 30.0}, s, 8, 0, c.responses, "sweep"
        )
        for s, c in zip((-1.0, 0.0, 0.9), datasets[3:6], strict=True)
    ]
    chart = predictions_chart(datasets, sweep, responses=("F", "z", "Fy"))
    assert chart.columns == 3 and len(chart.panels) == 9 and chart.reflow == "columns"
    assert [p.title for p in chart.panels[:3]] == [f"slip angle {a} deg" for a in (0, 30, 60)]
    labels = [p.y.label for p in chart.panels[::3]]
    assert labels == ["drawbar pull F [N]", "sinkage z [mm]", "lateral force Fy [N]"]
    for k, row in enumerate(("F", "z", "Fy")):
        panels = chart.panels[3 * k : 3 * k + 3]
        assert len({(p.y.lo, p.y.hi) for p in panels}) == 1  # a row on one y range
        for j, angle in enumerate((0.0, 30.0, 60.0)):
            mine = [c for c in datasets if c.conditions["slip_angle"] == angle]
            (bars,) = _layers(panels[j], "errorbars")
            assert bars["x"] == pytest.approx([c.slip_symmetric for c in mine], abs=1e-4)
            assert _ordered(bars["lo"], bars["y"], bars["hi"])
            (measured,) = _layers(panels[j], "points")
            scale = 1000.0 if row == "z" else 1.0
            want = [c.responses[row].measured * scale for c in mine]
            assert measured["y"] == pytest.approx(want, rel=1e-4)
            bands = _layers(panels[j], "band")
            assert len(bands) == (2 if angle == 30.0 else 0)  # the sweep at 30 deg only
            if bands:
                (median,) = _layers(panels[j], "line")
                assert _ordered(bands[0]["lo"], bands[1]["lo"], median["y"], bands[1]["hi"])
                assert _ordered(median["y"], bands[1]["hi"], bands[0]["hi"])
    # the lateral force grows with the angle: locked, about 1 N at 0 deg, 27 N at 30, 40 N at 60
    locked = [_layers(p, "points")[0]["y"][0] for p in chart.panels[6:9]]
    assert locked[0] < 2.0 < 20.0 < locked[1] < locked[2]
    # one legend, at 30 deg: the top panel that names the most (the sweep's bands too)
    assert [bool(p.legend) for p in chart.panels] == [False, True] + [False] * 7
    assert [bool(p.x.label) for p in chart.panels] == [False] * 6 + [True] * 3
    fig = draw(chart)  # the download: matplotlib draws the same grid
    shown = [ax for ax in fig.axes if ax.get_visible()]
    assert len(shown) == 9 and shown[2].get_title() == "slip angle 60 deg"
    assert shown[8].get_ylim() == pytest.approx(shown[6].get_ylim())


def test_a_study_at_one_slip_angle_names_it() -> None:
    chart = predictions_chart(_predictions((90.0,)), [])
    assert chart.columns == 1 and chart.panels[0].title == "slip angle 90 deg"
    assert [p.y.label.split()[-2] for p in chart.panels] == ["F", "z", "Fy"]


def test_a_straight_study_keeps_its_single_column() -> None:
    chart = predictions_chart(_predictions((0.0,), straight=True), [])
    assert chart.columns == 1 and chart.reflow == "rows" and chart.size == (7.0, 5.8)
    assert [p.title for p in chart.panels] == [None, None]
    assert all(p.y.lo is None and p.y.hi is None for p in chart.panels)


def _summary(r: dict[str, float]) -> SWTDataset:
    return load_summary(cmu_summary(r).encode(), name=cmu_name(r))


def test_a_steered_fit_has_a_column_per_angle_with_the_sigma_band() -> None:
    datasets = [_summary(r) for r in cmu_rows((0.0, 30.0)) if r["vry_cmd_mmps"] in (0, 100)]
    sims = [
        simulate_swt(rig=RigConfig(slip_angle=ds.conditions.slip_angle, W=20.0, **FAST))
        for ds in datasets
    ]
    sims[1] = None  # a failed simulation leaves a gap
    sigmas = {"F": 2.0, "Fy": 1.5, "z": 0.004}
    chart = slip_fit_chart(
        datasets, sims, responses=("F", "z", "Fy"), offsets={"z": -0.004}, sigmas=sigmas
    )
    assert chart.columns == 2 and len(chart.panels) == 6
    assert [p.title for p in chart.panels[:2]] == ["slip angle 0 deg", "slip angle 30 deg"]
    assert [p.y.label for p in chart.panels[::2]] == [
        "drawbar pull F [N]",
        "sinkage z [mm]",
        "lateral force Fy [N]",
    ]
    for k, (key, scale) in enumerate((("F", 1.0), ("z", 1000.0), ("Fy", 1.0))):
        for j in range(2):
            panel = chart.panels[2 * k + j]
            mine = [(ds, s) for ds, s in zip(datasets, sims, strict=True)][2 * j : 2 * j + 2]
            (sim,) = _layers(panel, "line")
            (bnd,) = _layers(panel, "band")
            assert sim["x"] == pytest.approx([-1.0, 0.8996], abs=1e-3)
            want = [
                None if s is None else (getattr(s.means, key) + (-0.004 if key == "z" else 0.0))
                for _, s in mine
            ]
            got = [None if v is None else v / scale for v in sim["y"]]
            assert got == [None if w is None else pytest.approx(w, rel=1e-4) for w in want]
            assert _ordered(
                [v for v in bnd["lo"] if v is not None],
                [v for v in sim["y"] if v is not None],
                [v for v in bnd["hi"] if v is not None],
            )
            hi = next(h for h in bnd["hi"] if h is not None)
            y = next(v for v in sim["y"] if v is not None)
            assert hi - y == pytest.approx(1.959964 * sigmas[key] * scale, rel=1e-3)
            (bars,) = _layers(panel, "errorbars")
            (pts,) = _layers(panel, "points")
            assert (
                bars["y"]
                == pts["y"]
                == pytest.approx([ds.responses[key].mean * scale for ds, _ in mine], rel=1e-4)
            )
            assert _ordered(bars["lo"], bars["y"], bars["hi"])
        assert chart.panels[2 * k].y == chart.panels[2 * k + 1].y
    fig = draw(chart)
    assert sum(ax.get_visible() for ax in fig.axes) == 6


def test_the_fit_of_a_straight_study_is_its_signals_in_time() -> None:
    """The dashboard's choice: a steered study's datasets get the fit against slip."""
    straight = [_summary(r) for r in cmu_rows((0.0,))]
    assert not steered(straight, dataset_angle)
    assert steered([*straight, _summary(cmu_rows((30.0,))[0])], dataset_angle)
    # the choice said once, for the dashboard and calibrate's fit_map.png
    assert not fits_against_slip(straight)
    assert fits_against_slip([*straight, _summary(cmu_rows((30.0,))[0])])


def test_calibrates_fit_map_png_of_a_steered_study_has_a_column_per_angle(tmp_path) -> None:
    """``scm-calib calibrate`` writes fit_map.png through :func:`plot_slip_fit` for a steered
    study: two slip angles, two columns (one for a study at one angle)."""
    from PIL import Image

    datasets = [_summary(r) for r in cmu_rows((0.0, 30.0)) if r["vry_cmd_mmps"] in (0, 100)]
    sims = [
        simulate_swt(rig=RigConfig(slip_angle=ds.conditions.slip_angle, W=20.0, **FAST))
        for ds in datasets
    ]
    path = plot_slip_fit(datasets, sims, tmp_path / "fit_map.png", responses=("F", "z", "Fy"))
    straight = plot_slip_fit(
        datasets[:2], sims[:2], tmp_path / "straight.png", responses=("F", "z", "Fy")
    )
    assert Image.open(path).size[0] > Image.open(straight).size[0]  # two columns, one
    assert slip_fit_chart(datasets, sims, responses=("F", "z", "Fy")).columns == 2


def test_the_clis_predictions_png_draws_the_same_grid(tmp_path) -> None:
    """``scm-calib predict`` writes predictions.png through :func:`plot_predictions`: a
    steered study's file has a column per slip angle (3 x 4.2 in at 120 dpi)."""
    from PIL import Image

    path = plot_predictions(_predictions((0.0, 30.0, 60.0)), [], tmp_path / "predictions.png")
    assert Image.open(path).size[0] == round(3 * 4.2 * 120)
