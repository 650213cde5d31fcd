"""Posterior predictions against slip: F, T, z with their 95 % bands and the measured points."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from scm_core.calibration.predict import Band, ConditionPrediction
from scm_core.signals.responses import RESPONSE_KEYS, RESPONSES

from .chart import Axis, Chart, Panel, band, errorbars, line, points, text, vline
from .figures import save
from .fit import wheel_label

_PANELS = tuple((r.key, r.label, r.scale) for r in RESPONSES)
_ROLE_STYLE = {
    "calibration": ("o", "black", "measured, used in the calibration"),
    "predicted": ("s", "red", "measured, held out"),
}
SLIP_LABEL = "slip (omega r - v) / max(v, omega r)  [-1 = locked]"
#: colours of the wheels of a study with several (a joint study of two wheels)
_WHEEL_COLORS = ("blue", "orange", "green", "purple", "brown")
#: slip offset between the wheels' bars at one slip, so that neither hides the other
DODGE = 0.02


def _by_wheel(shown: Sequence[ConditionPrediction]) -> list[tuple[str, list[ConditionPrediction]]]:
    """The datasets grouped by wheel (in order of appearance)."""
    groups: dict[str, list[ConditionPrediction]] = {}
    for c in shown:
        groups.setdefault(wheel_label(c.conditions), []).append(c)
    return list(groups.items())


def predictions_chart(
    datasets: Sequence[ConditionPrediction],
    sweep: Sequence[ConditionPrediction],
    title: str | None = None,
    responses: Sequence[str] = RESPONSE_KEYS,
) -> Chart:
    """One panel per response of ``responses`` that the predictions give (the lateral force
    only where predicted) against the symmetric lab slip (-1 = locked): the sweep's
    median and 95 % bands (simulated means, and with the prediction-error noise), each
    dataset's predicted median (a tick) and 95 % predictive interval (the bar), and its
    measurement where it has one (circles: used in the calibration; squares: held out). A
    study of several wheels draws each wheel's bars and points in a colour of its own, set
    apart by a small slip offset (``DODGE``), and names the wheel in the legend."""
    given = {r for c in (*datasets, *sweep) for r in c.responses}
    rows = [p for p in _PANELS if p[0] in responses and p[0] in given]
    sw = sorted((c for c in sweep if c.slip_symmetric is not None), key=lambda c: c.slip_symmetric)
    shown = [c for c in datasets if c.slip_symmetric is not None]
    panels: list[Panel | None] = []
    for k, (key, label, scale) in enumerate(rows):
        bottom = k == len(rows) - 1
        panel = Panel(
            Axis(SLIP_LABEL if bottom else "", tick_labels=bottom),
            Axis(label),
            legend="best" if k == 0 else None,
        )
        panel.add(vline(0.0, "grey", width=0.6))
        if sw:
            s = [c.slip_symmetric for c in sw]
            sim = [c.responses[key].simulated for c in sw]
            pred = [c.responses[key].predictive for c in sw]
            if all(p is not None for p in pred):
                panel.add(_band(s, pred, scale, 0.12, "95 % predictive band (with model error)"))
            panel.add(
                _band(s, sim, scale, 0.3, "95 % band of the simulated mean"),
                line(s, [b.median * scale for b in sim], width=1.5, label="posterior median"),
            )
        wheels = _by_wheel(shown)
        for w, (wheel, mine_w) in enumerate(wheels):
            several = len(wheels) > 1
            color = _WHEEL_COLORS[w % len(_WHEEL_COLORS)] if several else "blue"
            dodge = (w - (len(wheels) - 1) / 2) * DODGE if several else 0.0
            who = f"{wheel}: " if several else ""
            bands = [c.responses[key].predictive or c.responses[key].simulated for c in mine_w]
            kind = (
                "predictive interval"
                if all(c.responses[key].predictive is not None for c in mine_w)
                else "band of the mean"
            )
            panel.add(
                errorbars(
                    [c.slip_symmetric + dodge for c in mine_w],
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
                    c
                    for c in measured
                    if (c.role if c.role in _ROLE_STYLE else "predicted") == role
                ]
                if mine:
                    panel.add(
                        points(
                            [c.slip_symmetric + dodge for c in mine],
                            [c.responses[key].measured * scale for c in mine],
                            color if several else role_color,
                            size=3.5,
                            opacity=1.0,
                            symbol=symbol,
                            label=f"{who}{name}",
                        )
                    )
        if not any(c.responses[key].measured is not None for c in shown):
            panel.add(text("no measurement"))
        panels.append(panel)
    return Chart(
        title or "Posterior predictions across slip",
        panels,
        columns=1,
        size=(7.0, 2.6 * len(rows) + 0.6),
    )


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
) -> Path:
    """:func:`predictions_chart` drawn to ``path``."""
    from .mpl import draw

    return save(draw(predictions_chart(datasets, sweep, title, responses)), path, dpi=120)
