"""Posterior predictions against slip: F, T, z with their 95 % bands and the measured points;
a force map over slip and slip angle."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from scm_core.calibration.predict import Band, ConditionPrediction
from scm_core.signals.responses import RESPONSE_KEYS, RESPONSES

from .angles import angle_grid, angle_of, by_slip_angle, steered
from .chart import Axis, Chart, Panel, band, errorbars, line, points, text, viridis, vline
from .figures import save
from .fit import SLIP_LABEL, WHEEL_COLORS, wheel_label

_PANELS = tuple((r.key, r.label, r.scale) for r in RESPONSES)
_ROLE_STYLE = {
    "calibration": ("o", "black", "measured, used in the calibration"),
    "predicted": ("s", "red", "measured, held out"),
}
ANGLE_LABEL = "slip angle [deg] between the wheel's heading and its travel"
#: slip offset between the wheels' bars at one slip, so that neither hides the other
DODGE = 0.02


def _along(c: ConditionPrediction, along: str) -> float | None:
    """Where ``c`` lies along the chart's x: its symmetric slip, or its slip angle [deg]."""
    return c.slip_symmetric if along == "slip" else float(c.conditions.get("slip_angle") or 0.0)


def _by_wheel(shown: Sequence[ConditionPrediction]) -> list[tuple[str, list[ConditionPrediction]]]:
    """The datasets grouped by wheel (in order of appearance)."""
    groups: dict[str, list[ConditionPrediction]] = {}
    for c in shown:
        groups.setdefault(wheel_label(c.conditions), []).append(c)
    return list(groups.items())


def slip_angle_of(c: ConditionPrediction) -> float:
    """The slip angle of ``c``'s conditions [deg]; 0 (driven straight) where none is given."""
    return angle_of(c.conditions)


def predictions_chart(
    datasets: Sequence[ConditionPrediction],
    sweep: Sequence[ConditionPrediction],
    title: str | None = None,
    responses: Sequence[str] = RESPONSE_KEYS,
    along: str = "slip",
) -> Chart:
    """One panel per response of ``responses`` that the predictions give (the lateral force
    only where predicted) against the symmetric lab slip (-1 = locked; ``along`` "slip_angle":
    against the slip angle [deg], a slip-angle sweep's axis, in one column): the sweep's
    median and 95 % bands (simulated means, and with the prediction-error noise), each
    dataset's predicted median (a tick) and 95 % predictive interval (the bar), and its
    measurement where it has one (circles: used in the calibration; squares: held out). A
    study of several wheels draws each wheel's bars and points in a colour of its own, set
    apart by a small offset (``DODGE`` of a slip, 90 times that of an angle), and names the
    wheel in the legend.

    A steered study (a slip angle other than 0 among the conditions) gets a column per slip
    angle instead, ascending, a row per response on one y range
    (:func:`services.plots.angles.angle_grid`): each angle's datasets and sweep on its own
    slip axis."""
    given = {r for c in (*datasets, *sweep) for r in c.responses}
    rows = [p for p in _PANELS if p[0] in responses and p[0] in given]
    shown = [c for c in datasets if _along(c, along) is not None]
    swept = [c for c in sweep if _along(c, along) is not None]
    wheels = [w for w, _ in _by_wheel(shown)]
    title = title or "Posterior predictions across slip"
    if along != "slip" or not steered([*shown, *swept], slip_angle_of):
        panels: list[Panel | None] = [
            _panel(row, shown, swept, wheels, bottom=k == len(rows) - 1, legend=k == 0, along=along)
            for k, row in enumerate(rows)
        ]
        return Chart(title, panels, columns=1, size=(7.0, 2.6 * len(rows) + 0.6))
    data = dict(by_slip_angle(shown, slip_angle_of))
    sweeps = dict(by_slip_angle(swept, slip_angle_of))
    return angle_grid(
        title,
        rows,
        sorted({*data, *sweeps}),
        lambda row, a, bottom: _panel(
            row, data.get(a, []), sweeps.get(a, []), wheels, bottom, legend=False
        ),
    )


def _panel(
    row: tuple[str, str, float],
    shown: Sequence[ConditionPrediction],
    sweep: Sequence[ConditionPrediction],
    wheels: Sequence[str],
    bottom: bool,
    legend: bool,
    along: str = "slip",
) -> Panel:
    """The panel of one response (``row``: key, axis label, scale to the drawn unit) of the
    datasets ``shown`` and the ``sweep`` (both with a place ``along`` the x axis: the slip or
    the slip angle), the wheels coloured by their place in ``wheels``."""
    key, label, scale = row
    x_label = SLIP_LABEL if along == "slip" else ANGLE_LABEL
    step = DODGE if along == "slip" else 90.0 * DODGE
    panel = Panel(
        Axis(x_label if bottom else "", tick_labels=bottom),
        Axis(label),
        legend="best" if legend else None,
    )
    panel.add(vline(0.0, "grey", width=0.6))
    sw = sorted(sweep, key=lambda c: _along(c, along))
    if sw:
        s = [_along(c, along) for c in sw]
        sim = [c.responses[key].simulated for c in sw]
        pred = [c.responses[key].predictive for c in sw]
        if all(p is not None for p in pred):
            panel.add(_band(s, pred, scale, 0.12, "95 % predictive band (with model error)"))
        panel.add(
            _band(s, sim, scale, 0.3, "95 % band of the simulated mean"),
            line(s, [b.median * scale for b in sim], width=1.5, label="posterior median"),
        )
    several = len(wheels) > 1
    for wheel, mine_w in _by_wheel([c for c in shown if key in c.responses]):  # straight: no Fy
        w = wheels.index(wheel)
        color = WHEEL_COLORS[w % len(WHEEL_COLORS)] if several else "blue"
        dodge = (w - (len(wheels) - 1) / 2) * step if several else 0.0
        who = f"{wheel}: " if several else ""
        bands = [c.responses[key].predictive or c.responses[key].simulated for c in mine_w]
        kind = (
            "predictive interval"
            if all(c.responses[key].predictive is not None for c in mine_w)
            else "band of the mean"
        )
        panel.add(
            errorbars(
                [_along(c, along) + dodge for c in mine_w],
                [b.median * scale for b in bands],
                [b.lo * scale for b in bands],
                [b.hi * scale for b in bands],
                color,
                label=f"{who}predicted median, 95 % {kind}",
            )
        )
        measured = [c for c in mine_w if c.responses[key].measured is not None]
        for role, (symbol, role_color, name) in _ROLE_STYLE.items():
            # a role without a style of its own (a dataset not in the posterior) is held out
            mine = [
                c for c in measured if (c.role if c.role in _ROLE_STYLE else "predicted") == role
            ]
            if mine:
                panel.add(
                    points(
                        [_along(c, along) + dodge for c in mine],
                        [c.responses[key].measured * scale for c in mine],
                        color if several else role_color,
                        size=3.5,
                        opacity=1.0,
                        symbol=symbol,
                        label=f"{who}{name}",
                    )
                )
    if not any(key in c.responses and c.responses[key].measured is not None for c in shown):
        panel.add(text("no measurement"))
    return panel


def _band(
    slips: list[float], bands: Sequence[Band], scale: float, opacity: float, label: str
) -> dict[str, Any]:
    """The 95 % band of ``bands`` (one per slip) in the drawn unit."""
    return band(
        slips,
        [b.lo * scale for b in bands],
        [b.hi * scale for b in bands],
        opacity=opacity,
        label=label,
    )


def plot_predictions(
    datasets: Sequence[ConditionPrediction],
    sweep: Sequence[ConditionPrediction],
    path: str | Path,
    title: str | None = None,
    responses: Sequence[str] = RESPONSE_KEYS,
    along: str = "slip",
) -> Path:
    """:func:`predictions_chart` drawn to ``path``."""
    from .mpl import draw

    chart = predictions_chart(datasets, sweep, title, responses, along)
    return save(draw(chart), path, dpi=120)


def force_map_chart(grid: Sequence[ConditionPrediction], title: str | None = None) -> Chart:
    """A force map (the predictions of a :func:`~scm_core.calibration.predict.map_targets`
    ``grid``): one panel per response they give (F, T, z, Fy, in the figures' units) against
    the symmetric slip, one line (the posterior median) with its 95 % band of the simulated
    mean per slip angle."""
    given = {r for c in grid for r in c.responses}
    rows = [p for p in _PANELS if p[0] in given]
    angles = sorted({float(c.conditions.get("slip_angle", 0.0)) for c in grid})
    panels: list[Panel | None] = []
    for k, (key, label, scale) in enumerate(rows):
        bottom = k >= len(rows) - 2
        panel = Panel(
            Axis(SLIP_LABEL if bottom else "", tick_labels=bottom),
            Axis(label),
            legend="best" if k == 0 else None,
        )
        panel.add(vline(0.0, "grey", width=0.6))
        for j, a in enumerate(angles):
            mine = sorted(
                (c for c in grid if float(c.conditions.get("slip_angle", 0.0)) == a),
                key=lambda c: c.slip_symmetric,
            )
            s = [c.slip_symmetric for c in mine]
            sim = [c.responses[key].simulated for c in mine]
            color = viridis(j, len(angles))
            panel.add(
                band(
                    s,
                    [b.lo * scale for b in sim],
                    [b.hi * scale for b in sim],
                    color=color,
                    opacity=0.2,
                ),
                line(
                    s,
                    [b.median * scale for b in sim],
                    color,
                    width=1.5,
                    label=f"slip angle {a:g} deg",
                ),
            )
        panels.append(panel)
    return Chart(
        title or "Force map: posterior median and 95 % band",
        panels,
        columns=2,
        size=(11.0, 3.2 * ((len(rows) + 1) // 2) + 0.7),
    )


def plot_force_map(
    grid: Sequence[ConditionPrediction], path: str | Path, title: str | None = None
) -> Path:
    """:func:`force_map_chart` drawn to ``path``."""
    from .mpl import draw

    return save(draw(force_map_chart(grid, title)), path, dpi=120)
