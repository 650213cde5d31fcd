"""``scm-calib check FILE...``: validate SWT datasets and show what a study would use.

Each file is loaded as a study loads it (``scm_core.signals.load_dataset``: a time-series log when
its header has a time column, else a summary; JSON: a summary or a stored dataset). Printed per
file: the kind, the test conditions with both slips and both speeds, and the steady responses
(mean and standard error; for a log its averaging window). Then the warnings of
:mod:`scm_core.signals.checks`. Exit 0 when every file loads (warnings only), 1 when one does
not (its message names the file and what is wrong), 2 for a usage error.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from scm_core.signals import LogFormatError, SWTDataset, load_dataset
from scm_core.signals.checks import dataset_warnings, set_warnings
from scm_core.signals.responses import RESPONSES, Response


def _conditions(ds: SWTDataset) -> dict[str, Any]:
    c = ds.conditions
    return {
        "W_N": c.W,
        "slip_drive": c.slip,  # None for a locked wheel
        "slip_symmetric": c.slip_symmetric,
        "carriage_speed_m_s": c.carriage_speed,
        "rim_speed_m_s": c.rim_speed,
        "omega_rad_s": c.omega,
        "R_m": c.R,
        "b_m": c.b,
        "n_grousers": c.n_grousers,
        "grouser_height_m": c.grouser_height,
        "slip_angle_deg": c.slip_angle,
    }


def _report(ds: SWTDataset, path: Path) -> dict[str, Any]:
    out: dict[str, Any] = {
        "file": str(path),
        "name": ds.name,
        "kind": ds.source_kind,
        "conditions": _conditions(ds),
        "responses": {
            k: {"mean": ds.responses[k].mean, "se": ds.responses[k].se} for k in ds.responses
        },
    }
    if ds.source_kind == "summary":
        out["n_trials"] = ds.n_trials
    else:
        out["window_s"] = None if ds.window is None else list(ds.window)
        out["offset_s"] = ds.offset
        out["n_samples"] = ds.n_samples
        out["rate_hz"] = ds.rate_hz
    return out


def _shown(reports: list[dict[str, Any]]) -> list[Response]:
    """The responses a table shows: a steered wheel's (the lateral force) only where a file
    carries it."""
    carried = {k for r in reports for k in r["responses"]}
    return [r for r in RESPONSES if not r.steered or r.key in carried]


def _fmt(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def _print(reports: list[dict[str, Any]], warnings: list[str], errors: list[str]) -> None:
    console = Console(width=None if sys.stdout.isatty() else 160)
    table = Table(title="SWT datasets as a study reads them")
    steered = any(r["conditions"]["slip_angle_deg"] for r in reports)
    shown = _shown(reports)
    columns = ("file", "kind", "W [N]", "slip drive / sym.", "v / rim [mm/s]")
    columns += ("slip angle [deg]",) * steered
    columns += tuple(f"{resp.key} [{resp.shown_in}]" for resp in shown)
    for col in (*columns, "window / trials"):
        table.add_column(escape(col), justify="left" if col in ("file", "kind") else "right")
    for r in reports:
        c = r["conditions"]
        slip = (
            "locked"
            if c["slip_drive"] is None and c["slip_symmetric"] == -1.0
            else (f"{_fmt(c['slip_drive'], 3)} / {_fmt(c['slip_symmetric'], 3)}")
        )
        speeds = " / ".join(
            "-" if c[k] is None else f"{1000 * c[k]:.3g}"
            for k in ("carriage_speed_m_s", "rim_speed_m_s")
        )
        cells = []
        for resp in shown:
            stat = r["responses"].get(resp.key)
            scale = resp.scale
            cells.append(
                "absent"
                if stat is None
                else f"{scale * stat['mean']:.4g} ± {scale * stat['se']:.2g}"
            )
        if r["kind"] == "summary":
            extent = f"{r['n_trials']} trials"
        else:
            w = r["window_s"]
            extent = f"{w[0]:.4g}-{w[1]:.4g} s, {r['n_samples']} samples" if w else "-"
        angle = [_fmt(c["slip_angle_deg"] or 0.0, 3)] * steered
        first = (Path(r["file"]).name, r["kind"], _fmt(c["W_N"]), slip, speeds, *angle)
        table.add_row(*first, *cells, extent)
    if reports:
        console.print(table)
    for w in warnings:
        console.print(f"[yellow]warning:[/] {w}", soft_wrap=True)
    for e in errors:
        click.echo(f"error: {e}", err=True)


@click.command("check")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def check(files: tuple[Path, ...], as_json: bool) -> None:
    """Validate SWT datasets (time-series logs or summaries, CSV or JSON) and print what a
    study would use: conditions with both slips and both speeds, steady responses, windows,
    and warnings (a log without its time column, implausible magnitudes, a response measured in
    some files but not others). Exit 1 if a file does not load."""
    reports, loaded, labels, errors = [], [], [], []
    for path in files:
        try:
            ds = load_dataset(path)
        except OSError as exc:  # the file itself: one line, not Python's "[Errno 2] ..."
            errors.append(f"{path}: {(exc.strerror or str(exc)).lower()}")
            continue
        except (LogFormatError, ValueError) as exc:
            text = " ".join(str(exc).split())
            errors.append(text if path.name in text else f"{path}: {text}")
            continue
        reports.append(_report(ds, path))
        loaded.append(ds)
        labels.append(str(path))
    warnings = [
        w for ds, lab in zip(loaded, labels, strict=True) for w in dataset_warnings(ds, lab)
    ]
    if len(loaded) > 1:
        warnings += set_warnings(loaded, labels)
    if as_json:
        doc = {"datasets": reports, "warnings": warnings, "errors": errors}
        click.echo(json.dumps(doc, indent=2))
    else:
        _print(reports, warnings, errors)
    if errors:
        sys.exit(1)
