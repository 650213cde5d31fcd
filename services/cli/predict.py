"""``scm-calib predict``: posterior predictions of a finished study under other test conditions.

Reads a ``calibrate`` results folder (``summary.json`` holds the case, ``posterior.csv`` the
final samples), simulates ``--draws`` posterior samples under each dataset's test conditions,
at conditions nobody measured (``--at KEY=VALUE,...``), along ``--sweep slip=LO:HI:N`` (or
``slip_angle=LO:HI:N``) and over a force map's grid of slip and slip angle (``--map``), and
reports per dataset and response the median and 95 %
band of the simulated means, the same with the prediction-error noise, and the measured value
with whether it falls inside. Writes ``predictions.json`` and ``predictions.png`` to ``--out``
(default ``RESULTS_DIR/predictions``), and with ``--map`` ``force_map.csv`` and
``force_map.png``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import click
from rich.console import Console
from rich.table import Table

from scm_core.calibration import CaseDefinition, DatasetTerms
from scm_core.calibration.predict import (
    ConditionPrediction,
    map_targets,
    sweep_loads,
    sweep_targets,
)
from scm_core.seeds import SEED_MAX
from scm_core.signals import LogFormatError, SWTDataset
from scm_core.signals.metadata import merge_metadata
from scm_core.signals.responses import N_RESPONSES, RESPONSES
from services.studies import StudyRequestError
from services.studies.batching import local_batch_size
from services.studies.kinds import kind_of
from services.studies.kinds.prediction import PredictionRequest, prediction_spec
from worker.here import run_here

from .common import (
    CLIError,
    StudyFailed,
    as_option,
    compile_simulator_once,
    data_option,
    one_line_logs,
    option_group,
    read_datasets,
)
from .folder_store import FolderStore, open_folder_store
from .force_map import held_conditions, parse_map, parse_range, write_force_map
from .parent import load_parents, stored_posterior
from .results import write_json

_SCALE = {r.key: (r.scale, r.shown_in) for r in RESPONSES}


#: wheel geometry an ``--at`` condition takes from the study's datasets when it leaves it out
_GEOMETRY = ("R", "b", "n_grousers", "grouser_height")


def study_geometry(summary: dict[str, Any]) -> dict[str, float | int]:
    """The wheel geometry every dataset of the study shares (keys of :data:`_GEOMETRY`)."""
    conds = [d.get("conditions") or {} for d in summary.get("datasets", [])]
    out = {}
    for key in _GEOMETRY:
        values = {c.get(key) for c in conds}
        if conds and len(values) == 1 and None not in values:
            out[key] = values.pop()
    return out


def describe_wheel(geometry: dict[str, float | int | None]) -> str:
    """A wheel as a title names it, e.g. "R 58 mm, b 50 mm, 12 grousers of 5 mm" (lengths in
    m in ``geometry``, keys of :data:`_GEOMETRY`; those missing are left out)."""
    parts = [f"{k} {geometry[k] * 1000:.4g} mm" for k in ("R", "b") if geometry.get(k)]
    n, h = geometry.get("n_grousers"), geometry.get("grouser_height")
    if n and h:
        parts.append(f"{n} grousers of {h * 1000:.4g} mm")
    elif n == 0 or h == 0:
        parts.append("smooth")
    return ", ".join(parts)


def _wheel_key(conditions: dict[str, Any]) -> tuple[Any, ...]:
    """A wheel's geometry as a comparable key (no grousers and zero grousers alike)."""
    n, h = conditions.get("n_grousers") or 0, conditions.get("grouser_height") or 0
    return conditions.get("R"), conditions.get("b"), n if h else 0, h if n else 0


def prediction_title(
    case: CaseDefinition, summary: dict, datasets: list[SWTDataset], draws: int, runs: int = 1
) -> str:
    """The predictions figure's title: the study's case (with the number of runs pooled),
    and the predicted datasets' wheel where the study saw no test of it (a cross-wheel check
    names the wheel it predicts)."""
    drawn = f"{draws} draws" + (f" of {runs} runs pooled" if runs > 1 else "")
    title = f"{case.name}: posterior predictions ({drawn})"
    wheels = {_wheel_key(d.conditions.to_sim_config()) for d in datasets}
    own = {_wheel_key(d.get("conditions") or {}) for d in summary.get("datasets", [])}
    if len(wheels) != 1 or wheels <= own:
        return title
    wheel = dict(zip(_GEOMETRY, wheels.pop(), strict=True))
    return f"{case.name}'s posterior on another wheel ({describe_wheel(wheel)}), {drawn}"


def map_title(case: CaseDefinition, points: list[ConditionPrediction], draws: int) -> str:
    """The force map figure's title: the case, the draws, the wheel and the load it holds."""
    cond = points[0].conditions
    wheel = describe_wheel(cond)
    held = ", ".join(x for x in (wheel, f"W {cond['W']:.4g} N" if "W" in cond else "") if x)
    return f"{case.name}: force map, median and 95 % band of {draws} draws; {held}"


def parse_at(specs: tuple[str, ...], geometry: dict[str, float | int]) -> list[DatasetTerms]:
    """``--at W=25,slip=0.3`` -> test conditions with no measurement (metadata keys and units as
    in a lab file's ``# key: value`` lines, docs/data-formats.md); the wheel geometry it leaves
    out is the study's (``geometry``), so a condition is the calibrated wheel's unless it says
    otherwise."""
    out = []
    for spec in specs:
        pairs = [p.partition("=") for p in spec.split(",") if p.strip()]
        if not pairs or any(not sep or not k.strip() for k, sep, _ in pairs):
            raise CLIError(f"--at {spec!r}: expected KEY=VALUE,KEY=VALUE, e.g. W=25,slip=0.3")
        raw = {k.strip(): v.strip() for k, _, v in pairs}
        try:
            meta = merge_metadata([(f"--at {spec}", raw)])
        except (LogFormatError, ValueError) as exc:
            raise CLIError(f"--at {spec!r}: {' '.join(str(exc).split())}") from None
        conditions = {**geometry, **meta.conditions.to_sim_config()}
        out.append(DatasetTerms(f"at {spec}", conditions, (math.nan,) * N_RESPONSES))
    return out


def _sweep_key(spec: str | None) -> str:
    """What ``--sweep`` varies ("slip" without a sweep): a predictions figure's x axis."""
    sweep = parse_sweep(spec)
    return sweep[0] if sweep else "slip"


def parse_sweep(spec: str | None) -> tuple[str, list[float]] | None:
    """``slip=LO:HI:N`` -> ("slip", N symmetric slips from LO to HI, -1 = locked);
    ``slip_angle=LO:HI:N`` -> ("slip_angle", N slip angles [deg] within [-90, 90]); lab
    aliases of either key (``beta``, ``steering_angle`` ...) too; None without a sweep."""
    return None if spec is None else parse_range("--sweep", spec)


@dataclass(frozen=True)
class _Targets:
    """Where to predict: datasets' conditions, conditions nobody measured, a sweep of the slip
    or the slip angle, a force map over both."""

    data: tuple[Path, ...]
    at: tuple[str, ...]
    sweep: str | None
    force_map: str | None


@dataclass(frozen=True)
class _Where:
    """The conditions of :class:`_Targets`: datasets, --at conditions, the sweep's, the map's."""

    datasets: list[SWTDataset]
    at: list[DatasetTerms]
    sweep: list[DatasetTerms]
    map: list[DatasetTerms]


def _conditions(case: CaseDefinition, summary: dict, targets: _Targets) -> _Where:
    """The conditions of ``targets``; the sweep and the map run at the first dataset's
    conditions (else the first --at's, else the study's first dataset's); a slip sweep with
    the load interpolated between the datasets' loads, a slip-angle sweep and the map at the
    template's load."""
    sweep = parse_sweep(targets.sweep)
    grid = parse_map(targets.force_map)
    at_terms = parse_at(targets.at, study_geometry(summary))
    if not targets.data and not sweep and not grid and not at_terms:
        raise CLIError(
            "nothing to predict: give --data DATASET (repeatable), --at KEY=VALUE,..., "
            "--sweep and/or --map"
        )
    datasets = read_datasets(case, list(targets.data)) if targets.data else []
    if not sweep and not grid:
        return _Where(datasets, at_terms, [], [])
    loads = None
    if datasets:
        terms = [
            DatasetTerms(d.name, d.conditions.to_sim_config(), (math.nan,) * N_RESPONSES)
            for d in datasets
        ]
        template = terms[0]
        loads = sweep_loads(terms)
    elif at_terms:
        template = at_terms[0]
    else:
        first = (summary.get("datasets") or [{}])[0]
        template = DatasetTerms(
            "study", dict(first.get("conditions") or {}), (math.nan,) * N_RESPONSES
        )
    swept = sweep_targets(template, sweep[1], loads, key=sweep[0]) if sweep else []
    return _Where(datasets, at_terms, swept, map_targets(template, *grid) if grid else [])


@click.command()
@click.argument("results", type=click.Path(file_okay=False, path_type=Path))
@click.argument("more_data", nargs=-1, type=click.Path(dir_okay=False, path_type=Path))
@option_group(
    "targets",
    _Targets,
    data_option("SWT log or summary whose test conditions to predict; --data A B C or repeated."),
    click.option(
        "--at",
        "at",
        multiple=True,
        metavar="KEY=VALUE,...",
        help="Also predict at test conditions nobody measured, e.g. --at W=25,slip=0.3 "
        "(keys and units as in a lab file's metadata; the wheel geometry left out is the "
        "study's datasets'; repeatable).",
    ),
    click.option(
        "--sweep",
        default=None,
        metavar="slip|slip_angle=LO:HI:N",
        help="Also predict along a slip sweep (symmetric convention, -1 = locked) at the "
        "first dataset's conditions, with the load interpolated between the datasets' loads "
        "when several are given; or along slip_angle=LO:HI:N (deg, -90..90; or a lab's name: "
        "beta, steering_angle) at those conditions and load.",
    ),
    click.option(
        "--map",
        "force_map",
        is_flag=False,
        flag_value="",
        default=None,
        metavar="[slip=LO:HI:N,slip_angle=LO:HI:N]",
        help="Also write the force map a vehicle model reads: F, T, z, Fy (median and 95 % "
        "band of the simulated mean, SI) over a grid of slip x slip angle [deg] at the first "
        "dataset's conditions and load, as force_map.csv and force_map.png. Bare: "
        "slip=-0.9:0.9:19,slip_angle=0:90:7; an axis left out takes that default; at most "
        "200 points.",
    ),
)
@click.option(
    "--draws",
    type=click.IntRange(1, 100_000),
    default=200,
    show_default=True,
    help="Posterior samples to simulate.",
)
@click.option("--seed", type=click.IntRange(min=0, max=SEED_MAX), default=0, show_default=True)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Output folder [default: RESULTS/predictions].",
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Simulate on N processes [default: in-process, all cores].",
)
@click.option("--json", "as_json", is_flag=True, help="Print the predictions as JSON.")
@click.option("--no-plots", is_flag=True, help="Skip the figure.")
def predict_cmd(
    results: Path,
    more_data: tuple[Path, ...],
    targets: _Targets,
    draws: int,
    seed: int,
    out: Path | None,
    workers: int | None,
    as_json: bool,
    no_plots: bool,
) -> None:
    """Predict F, T, z (and a steered wheel's Fy) of the study in RESULTS (a `calibrate`
    output folder, or a run group's folder: its runs' pooled posterior) under the test
    conditions of other datasets, with 95 % posterior bands.

    The predictions are studies of RESULTS's database made by the service's prediction kind
    (one per kind of target: datasets, --at conditions, the sweep, the map) and run by its
    batches."""
    parents = load_parents(results, "predict")
    case, summary = parents[0].case, parents[0].summary
    targets = replace(targets, data=(*targets.data, *more_data))
    where = _conditions(case, summary, targets)
    compile_simulator_once(as_json)
    with open_folder_store(results, workers, "predict") as folder:
        posterior = [stored_posterior(folder, p, "predict").id for p in parents]
        ids = folder.add_datasets(where.datasets, list(targets.data))
        run = partial(_predict, folder, posterior, draws, seed, workers)
        preds = run(ids, None, "") if ids else []
        untested = run(None, where.at, "untested") if where.at else []
        swept = run(None, where.sweep, "sweep") if where.sweep else []
        mapped = run(None, where.map, "map") if where.map else []
    doc = {
        "format": "scm-calib-predictions",
        "version": 1,
        "study": {
            "case": case.name,
            "case_hash": summary.get("case_hash"),
            "results": str(results),
            "runs": len(parents),
        },
        "draws": draws,
        "seed": seed,
        "level": 0.95,
        "datasets": [p.to_dict(draws=True) for p in preds],
        "conditions": [p.to_dict() for p in untested],
        "sweep": [p.to_dict() for p in swept],
        "map": [p.to_dict() for p in mapped],
    }
    out = out or results / "predictions"
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"--out {out}: {exc.strerror or exc}") from None
    write_json(out / "predictions.json", doc, indent=2)
    if mapped:
        about = {"case": case.name, "results": str(results), "runs": len(parents)}
        about |= {"draws": draws, "seed": seed, **held_conditions(where.map[0].conditions)}
        write_force_map(out / "force_map.csv", mapped, about)
    if not no_plots:
        from services.plots.predict import plot_force_map, plot_predictions

        if preds or untested or swept:
            plot_predictions(
                preds + untested,
                swept,
                out / "predictions.png",
                title=prediction_title(case, summary, where.datasets, draws, len(parents)),
                responses=_shown_responses(case, preds + untested + swept),
                along=_sweep_key(targets.sweep),
            )
        if mapped:
            plot_force_map(mapped, out / "force_map.png", title=map_title(case, mapped, draws))
    if as_json:
        click.echo(json.dumps(doc, indent=2))
        return
    if preds or untested or not mapped:
        _print_table(preds + untested)
    if mapped:
        click.echo(f"force map of {len(mapped)} points (slip x slip angle): force_map.csv")
    click.echo(f"written to {out}")


#: the prediction kind's request fields, as this command's options
_OPTIONS = {"draws": "--draws", "seed": "--seed", "dataset_ids": "--data", "conditions": "--at"}


def _predict(
    folder: FolderStore,
    study_ids: list[int],
    draws: int,
    seed: int,
    workers: int | None,
    dataset_ids: list[int] | None,
    conditions: list[DatasetTerms] | None,
    role: str,
) -> list[ConditionPrediction]:
    """The predictions of the folder's study ``study_ids[0]`` (pooled with the other runs
    ``study_ids[1:]`` of its calibration) under ``dataset_ids`` or ``conditions`` (a
    prediction study of the folder, run here or found done); ``role`` labels those of
    conditions ("untested", "sweep", "map")."""
    body = PredictionRequest(
        study_id=study_ids[0],
        pooled_with=study_ids[1:],
        dataset_ids=dataset_ids,
        conditions=None
        if conditions is None
        else [{"name": t.name, **t.conditions} for t in conditions],
        draws=draws,
        seed=seed,
        batch_size=local_batch_size(draws, workers),
    )
    try:
        spec = prediction_spec(folder.store, folder.settings, body)
    except StudyRequestError as exc:
        option = {"sweep": "--sweep", "map": "--map"}.get(role, "--at")
        raise CLIError(as_option(str(exc), {**_OPTIONS, "conditions": option})) from None
    record = folder.find(spec) or folder.store.studies.create(spec)
    try:
        with one_line_logs():
            record = run_here(folder.store, record.id, folder.settings, workers)
    except KeyboardInterrupt:
        click.echo("interrupted: re-run the same command to go on", err=True)
        raise SystemExit(130) from None
    if record.status != "completed":
        raise StudyFailed(f"the prediction ended {record.status}: {record.error}")
    preds = kind_of(record.kind).build(folder.store, record).stored(folder.store, record)
    return [p if not role else dataclasses.replace(p, role=role) for p in preds]


def _shown_responses(case: CaseDefinition, preds: list[ConditionPrediction]) -> tuple[str, ...]:
    """The case's responses plus any other one a dataset measured, and a steered wheel's
    (the lateral force) where a condition is steered."""
    measured = {r for p in preds for r, x in p.responses.items() if x.measured is not None}
    steered = any(p.conditions.get("slip_angle") for p in preds)
    return tuple(
        r.key
        for r in RESPONSES
        if r.key in case.responses or r.key in measured or (r.steered and steered)
    )


def _print_table(preds: list[ConditionPrediction]) -> None:
    console = Console()
    if not console.is_terminal:
        console = Console(width=132)  # a log file: no wrapped cells
    table = Table(title="posterior predictions: median [95 % predictive band]")
    for col in ("dataset", "role", "slip", "response", "median", "95 % band", "measured", "inside"):
        table.add_column(col, justify="left" if col in ("dataset", "role", "response") else "right")
    for p in preds:
        for r, x in p.responses.items():
            scale, unit = _SCALE[r]
            band = x.predictive or x.simulated
            inside = x.inside_predictive if x.predictive is not None else x.inside_simulated
            table.add_row(
                p.name,
                p.role,
                "-" if p.slip_symmetric is None else f"{p.slip_symmetric:.3g}",
                r,
                f"{band.median * scale:.4g} {unit}",
                f"{band.lo * scale:.4g} .. {band.hi * scale:.4g}",
                "-" if x.measured is None else f"{x.measured * scale:.4g}",
                "-" if inside is None else ("yes" if inside else "NO"),
            )
    console.print(table)
