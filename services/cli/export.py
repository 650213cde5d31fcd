"""``scm-calib export DIR --to netcdf``: a ``calibrate`` results folder for other tools.

``netcdf``: an ArviZ InferenceData file (``services.exports.inference_data``: posterior,
prior, sample statistics, observed data), read back by ``arviz.from_netcdf``; default
``DIR/inference_data.nc``.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import click
import numpy as np

from .common import CLIError

FORMATS = ("netcdf",)


def read_population(path: Path, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(samples (n, d), log_likelihood (n,), log_prior (n,)) of a stage CSV of a results
    folder (``posterior.csv``, ``samples/stage_NN.csv``), exactly as written."""
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise CLIError(f"{path}: {exc.strerror or exc}") from None
    if not rows:
        raise CLIError(f"{path}: empty file")
    header = rows[0]
    wanted = [*names, "log_likelihood", "log_prior"]
    missing = [c for c in wanted if c not in header]
    if missing:
        raise CLIError(f"{path}: no column {', '.join(missing)}; is this a results folder?")
    cols = [header.index(c) for c in wanted]
    try:
        table = np.array([[float(r[c]) for c in cols] for r in rows[1:]], dtype=float)
    except (ValueError, IndexError) as exc:
        raise CLIError(f"{path}: unreadable row ({exc})") from None
    table = table.reshape(-1, len(wanted))
    d = len(names)
    return table[:, :d], table[:, d], table[:, d + 1]


def _float(v: object) -> float:
    return math.nan if v is None else float(v)  # type: ignore[arg-type]


def results_inference_data(results: Path):
    """The InferenceData of a ``calibrate`` results folder (one run: one chain)."""
    from services.exports.inference_data import RunPopulation, StageRow, inference_data

    summary_path = results / "summary.json"
    if not summary_path.is_file():
        raise CLIError(
            f"{results}: no summary.json; give the output folder of `scm-calib calibrate`"
        )
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
        names = list(summary["parameters"])
    except (OSError, json.JSONDecodeError, KeyError, TypeError) as exc:
        raise CLIError(f"{summary_path}: unreadable study summary ({exc})") from None
    samples, ll, lp = read_population(results / "posterior.csv", names)
    prior, _, _ = read_population(results / "samples" / "stage_00.csv", names)
    stages = [
        StageRow(*(_float(s.get(k)) for k in ("exponent", "acceptance_rate", "log_evidence")))
        for s in summary.get("stages") or []
    ]
    run = RunPopulation(samples, ll, lp, prior, stages)
    observed = {
        d["name"]: {k: d.get(k) or {} for k in ("means", "standard_errors")}
        for d in summary.get("datasets") or []
    }
    attrs = {
        "case": summary.get("case"),
        "status": summary.get("status"),
        "is_posterior": bool(summary.get("is_posterior", summary.get("status") == "completed")),
        "log_evidence": summary.get("log_evidence"),
        "log_evidence_se": summary.get("log_evidence_se"),
        "seed": (summary.get("settings") or {}).get("seed"),
    }
    return inference_data(names, [run], units=summary.get("units"), observed=observed, attrs=attrs)


@click.command("export")
@click.argument("results", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "--to", "fmt", type=click.Choice(FORMATS), default="netcdf", show_default=True,
    help="netcdf: an ArviZ InferenceData file (arviz.from_netcdf reads it).",
)  # fmt: skip
@click.option(
    "--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
    help="The file to write (default RESULTS/inference_data.nc).",
)  # fmt: skip
def export(results: Path, fmt: str, out: Path | None) -> None:
    """Export the calibration in RESULTS (a `scm-calib calibrate` folder) for other tools."""
    import warnings

    with warnings.catch_warnings():  # ArviZ announces its refactor on import
        warnings.simplefilter("ignore", FutureWarning)
        idata = results_inference_data(results)
    target = out or results / "inference_data.nc"
    try:
        idata.to_netcdf(str(target))
    except OSError as exc:
        raise CLIError(f"{target}: {exc.strerror or exc}") from None
    status = str(idata.posterior.attrs.get("status"))
    chains, draws = idata.posterior.sizes["chain"], idata.posterior.sizes["draw"]
    click.echo(f"wrote {target} ({chains} chain x {draws} draws, {status})")
    if not idata.posterior.attrs.get("is_posterior"):
        click.echo(f"warning: {results} holds a {status} run: NOT A POSTERIOR", err=True)
