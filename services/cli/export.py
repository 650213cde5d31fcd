"""``scm-calib export DIR --to netcdf|chrono|stages``: a ``calibrate`` results folder for other
tools.

``netcdf``: an ArviZ InferenceData file (``services.exports.inference_data``: posterior,
prior, sample statistics, observed data), read back by ``arviz.from_netcdf``; default
``DIR/inference_data.nc``.

``chrono``: the soil at the MAP and at the posterior medians (and ``--draws`` posterior
samples) as Chrono's ``SCMTerrain::SetSoilParameters`` calls for C++ and PyChrono and a JSON
block, with the units stated (``services.exports.chrono``); default ``DIR/chrono_soil.json``
beside ``chrono_soil.cpp`` and ``chrono_soil.py``.

``stages``: every stage of the study, bit for bit, as ``stage_NNN.json`` (``StageState.to_dict()``
and its wall time) with a ``manifest.json``, written from the folder's database (where the
stages are kept, once); default ``DIR/stages/``.
"""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from services.stages import FolderStages, StageStoreError, run_population, stage_states

from .common import CLIError
from .results import load_results, results_stages, write_json
from .runs import diagnose_folders, group_folders, pooled_posterior

FORMATS = ("netcdf", "chrono", "stages")
STAGES_FORMAT = "scm-calib-stages"


def _run(results: Path):
    """(case, summary, RunPopulation) of one ``calibrate`` results folder."""
    case, _, summary = load_results(results)
    try:
        with results_stages(results, summary) as stages:
            return case, summary, run_population(stages)
    except StageStoreError as exc:
        raise CLIError(f"{results}: {exc}") from None


def write_stages(results: Path, out: Path) -> None:
    """The stages of ``results`` as JSON files, ``out/stage_NNN.json`` (each
    ``{"state": StageState.to_dict(), "wall_time_s": seconds}``, exact) and ``out/manifest.json``
    (what study they are): the form folders kept before they held a database."""
    case, _, summary = load_results(results)
    walls = [s.get("wall_time_s") or 0.0 for s in summary.get("stages") or []]
    target = FolderStages(results, directory=out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"--out {out}: {exc.strerror or exc}") from None
    if target.count():
        raise CLIError(f"--out {out}: holds stage files already; give an empty folder")
    try:
        with results_stages(results, summary) as stages:
            states = stage_states(stages)
        for state in states:
            wall = walls[state.stage] if state.stage < len(walls) else 0.0
            target.save(state, float(wall))
    except (StageStoreError, OSError) as exc:
        raise CLIError(f"{results}: {exc}") from None
    manifest = {
        "format": STAGES_FORMAT,
        "case": case.name,
        "case_hash": summary.get("case_hash") or case.fingerprint(),
        "data_hashes": [d.get("content_hash") for d in summary.get("datasets") or []],
        "parameters": list(case.parameter_names),
        "seed": case.seed,
        "status": summary.get("status"),
        "n_stages": len(states),
        "results": str(results.resolve()),
    }
    write_json(out / "manifest.json", manifest, indent=2)
    click.echo(f"wrote {len(states)} stages to {out}")


def _predicted(results: Path, summary: dict) -> dict[str, dict[str, list]] | None:
    """Each predicted draw per dataset and response from ``RESULTS/predictions`` (written by
    ``scm-calib predict`` for this study), or None."""
    path = results / "predictions" / "predictions.json"
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise CLIError(f"{path}: unreadable predictions ({exc})") from None
    if (doc.get("study") or {}).get("case_hash") != summary.get("case_hash"):
        return None  # predictions of another study in this folder
    return {
        d["name"]: {r: v["draws"] for r, v in d["responses"].items() if "draws" in v}
        for d in doc.get("datasets") or []
    }


def results_inference_data(results: Path):
    """The InferenceData of a ``calibrate`` results folder (one run: one chain), or of a run
    group's folder (``calibrate --runs K``: one chain per run, the verdict in the attributes)."""
    from services.exports.inference_data import inference_data

    folders = group_folders(results)
    if folders is not None:
        _, verdict = diagnose_folders(folders)
    else:
        folders, verdict = [results], None
    loaded = [_run(f) for f in folders]
    case, summary, _ = loaded[0]
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
    if verdict is not None:
        attrs.update(
            seed=[s.get("case", {}).get("seed") for _, s, _ in loaded],
            log_evidence=list(verdict.log_evidence),
            log_evidence_se=list(verdict.log_evidence_se),
            rhat={p.name: p.rhat for p in verdict.parameters},
            converged=verdict.converged,
            verdict=verdict.line(),
        )
    try:
        return inference_data(
            list(case.parameter_names),
            [run for _, _, run in loaded],
            units=summary.get("units"),
            observed=observed,
            attrs=attrs,
            predictive=None if verdict is not None else _predicted(results, summary),
        )
    except ValueError as exc:
        raise CLIError(f"{results}: {exc}") from None


def write_chrono(results: Path, out: Path, draws: int, seed: int, lossy: bool) -> None:
    """The Chrono export of ``results`` to ``out`` (JSON) and its .cpp and .py siblings."""
    from pydantic import ValidationError

    from scm_core.calibration.model import build_configs
    from services.exports.chrono import (
        ChronoExportError,
        chrono_soil,
        cpp_call,
        python_call,
        soils_document,
    )

    folders = group_folders(results)
    if folders is None:
        case, samples, summary = load_results(results)
        map_values = (summary.get("posterior") or {}).get("map")
        status = summary.get("status")
    else:  # a run group: the pooled posterior of its runs (all completed, one study)
        case, samples, map_values = pooled_posterior(folders)
        status = f"completed, {len(folders)} runs pooled"
    names = list(case.parameter_names)
    points = {"posterior median": dict(zip(names, np.median(samples, axis=0), strict=True))}
    if map_values:
        points = {"MAP": {k: float(v) for k, v in map_values.items()}, **points}
    rng = np.random.default_rng(seed)
    picks = rng.choice(samples.shape[0], size=draws, replace=True) if draws else []
    draw_points = [dict(zip(names, samples[i], strict=True)) for i in picks]

    def soil_at(values: dict, label: str) -> tuple:
        try:
            soil, _, rig = build_configs(case.nominal, case.simulator, {}, values)
        except (ValidationError, ValueError) as exc:
            raise CLIError(f"{results}: the {label} soil does not build ({exc})") from None
        try:
            return chrono_soil(soil, rig, lossy=lossy)
        except ChronoExportError as exc:  # the values quoted are this set's: say which
            raise CLIError(f"the {label} soil: {exc}") from None

    sets = {}
    dropped: list[str] = []  # what each named set lost, said with the set's name
    for label, values in points.items():
        sets[label], lost = soil_at(values, label)
        dropped += [f"{label}: {item}" for item in lost]
    draw_sets = [soil_at(v, f"draw {k + 1}")[0] for k, v in enumerate(draw_points)]
    doc = soils_document(sets, dropped, draw_sets)
    doc["study"] = {"case": case.name, "status": status, "results": str(results)}
    write_json(out, doc, indent=2)
    what = f"{case.name} ({status})"
    cpp = "".join(cpp_call(s, comment=f"{what}: {label}") for label, s in sets.items())
    py = "".join(python_call(s, comment=f"{what}: {label}") for label, s in sets.items())
    out.with_suffix(".cpp").write_text(cpp, encoding="utf-8")
    out.with_suffix(".py").write_text(py, encoding="utf-8")
    click.echo(cpp, nl=False)
    click.echo(f"wrote {out}, {out.with_suffix('.cpp').name}, {out.with_suffix('.py').name}")
    for item in dropped:
        click.echo(f"warning: dropped (--lossy): {item}", err=True)


@click.command("export")
@click.argument("results", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "--to", "fmt", type=click.Choice(FORMATS), default="netcdf", show_default=True,
    help="netcdf: an ArviZ InferenceData file (arviz.from_netcdf reads it); chrono: "
    "SCMTerrain::SetSoilParameters calls and a JSON block; stages: every stage as exact JSON "
    "(stage_NNN.json and manifest.json; the study's database holds them).",
)  # fmt: skip
@click.option(
    "--out", type=click.Path(path_type=Path), default=None,
    help="The file to write (default RESULTS/inference_data.nc or RESULTS/chrono_soil.json); "
    "stages: the folder (default RESULTS/stages).",
)  # fmt: skip
@click.option("--draws", type=click.IntRange(0, 100_000), default=0, show_default=True,
              help="chrono: also this many posterior samples (drawn with --seed).")  # fmt: skip
@click.option("--seed", type=click.IntRange(0), default=0, show_default=True,
              help="chrono: seed of the --draws.")  # fmt: skip
@click.option("--lossy", is_flag=True,
              help="chrono: export what Chrono can take and list what was dropped.")  # fmt: skip
def export(results: Path, fmt: str, out: Path | None, draws: int, seed: int, lossy: bool) -> None:
    """Export the calibration in RESULTS (a `scm-calib calibrate` folder, or a `--runs`
    group's folder: one chain per run in netcdf, the pooled posterior for chrono) for other
    tools."""
    if fmt == "stages":
        if group_folders(results) is not None and not (results / "summary.json").is_file():
            raise CLIError(f"{results}: a group of runs; give one run's folder, e.g. run_1")
        target = out or results / "stages"
        if target.exists() and not target.is_dir():
            raise CLIError(f"--out {target}: not a folder")
        write_stages(results, target)
        return
    if out is not None and out.is_dir():
        raise CLIError(f"--out {out}: a folder; give the file to write")
    if fmt == "chrono":
        write_chrono(results, out or results / "chrono_soil.json", draws, seed, lossy)
        return
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
    chains, draws_n = idata.posterior.sizes["chain"], idata.posterior.sizes["draw"]
    click.echo(f"wrote {target} ({chains} chain x {draws_n} draws, {status})")
    if not idata.posterior.attrs.get("is_posterior"):
        click.echo(f"warning: {results} holds a {status} run: NOT A POSTERIOR", err=True)
