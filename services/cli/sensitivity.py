"""``scm-calib sensitivity``: Morris screening of the soil parameters (paper section 4.4)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click
from rich.console import Console
from rich.table import Table

from scm_core.calibration import MorrisSettings
from scm_core.calibration.failures import describe_failures
from scm_core.seeds import SEED_MAX
from services.studies import StudyRequestError, sensitivity_spec
from services.studies.batching import local_batch_size
from worker.here import run_here

from .common import (
    CLIError,
    StudyFailed,
    as_option,
    compile_simulator_once,
    data_paths,
    one_line_logs,
    read_case,
    read_datasets,
)
from .folder_store import open_folder_store
from .results import write_json


def _parse_bounds(items: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    for item in items:
        name, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        try:
            if not (sep and sep2 and name.strip()):
                raise ValueError
            out[name.strip()] = (float(lo), float(hi))
        except ValueError:
            raise CLIError(f"--bounds: expected NAME=LOWER:UPPER, got {item!r}") from None
    return out


@click.command()
@click.argument("case_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--data",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="SWT log or summary whose test conditions are simulated [default: the case's first].",
)
@click.option(
    "--r",
    "r",
    default=20,
    show_default=True,
    type=click.IntRange(min=2),
    help="Morris trajectories.",
)
@click.option(
    "--levels", default=4, show_default=True, type=click.IntRange(min=2), help="Grid levels (even)."
)
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0, max=SEED_MAX))
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    help="Output directory [default: ./<case file stem>_sensitivity].",
)
@click.option(
    "--separate-k",
    is_flag=True,
    help="Screen k_c and k_phi separately instead of jointly through k* (the paper's choice).",
)
@click.option(
    "--bounds",
    "bounds",
    multiple=True,
    metavar="NAME=LOWER:UPPER",
    help="Bounds of a factor (repeatable), e.g. --bounds c=0:500.",
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Run on N processes [default: in-process, all cores].",
)
def sensitivity(
    case_file: Path,
    data: Path | None,
    r: int,
    levels: int,
    seed: int,
    out: Path | None,
    separate_k: bool,
    bounds: tuple[str, ...],
    workers: int | None,
) -> None:
    """Morris screening of the 7 SCM soil parameters (Table 1) on the steady F, T, z under the
    test conditions of one dataset, with the case's nominal values and simulator settings.

    The screening is a study of OUT's database (OUT/study.db), run by the service's
    screening kind: interrupt it with Ctrl-C and re-run the same command to go on with the
    design points not yet run."""
    case = read_case(case_file)
    if levels % 2:
        raise CLIError(f"--levels must be even, got {levels}")
    paths = [data] if data is not None else data_paths(case, ())[:1]
    datasets = read_datasets(case, paths)
    morris = MorrisSettings(r, levels, seed, not separate_k, _parse_bounds(bounds))
    out = out or Path(f"{case_file.stem}_sensitivity")
    with open_folder_store(out, workers) as folder:
        (dataset_id,) = folder.add_datasets(datasets, paths)
        try:
            spec = sensitivity_spec(
                folder.store,
                folder.settings,
                case,
                dataset_id,
                morris,
            )
        except StudyRequestError as exc:
            raise CLIError(as_option(str(exc), _OPTIONS)) from None
        spec = replace(spec, batch_size=local_batch_size(spec.n_samples, workers))
        study = folder.study_for(spec, "a sensitivity study")
        compile_simulator_once()
        try:
            with one_line_logs():
                study = run_here(folder.store, study.id, folder.settings, workers)
        except KeyboardInterrupt:
            click.echo(
                f"interrupted: the design points run so far are kept in {out}; re-run the "
                "same command to go on",
                err=True,
            )
            raise SystemExit(130) from None
    if study.status != "completed" or not study.result:
        raise StudyFailed(f"the screening ended {study.status}: {study.error}")
    res = study.result
    doc = {
        "case": case.name,
        "joint_k": not separate_k,
        "dataset_hash": datasets[0].content_hash,
        "conditions": datasets[0].conditions.to_sim_config(),
        **res,
    }
    write_json(out / "sensitivity.json", doc, indent=2)
    from services.plots.sensitivity import plot_indices

    plot_indices(res, out / "sensitivity.png")
    _print_indices(res, out)


#: the screening kind's request fields, as this command's options
_OPTIONS = {"bounds": "--bounds", "r": "--r", "levels": "--levels", "dataset_id": "--data"}


def _print_indices(res: dict, out: Path) -> None:
    failed = describe_failures(res["n_failed_runs"], res.get("failed_runs_by", {}))
    table = Table(
        title=f"Morris screening, {res['n_runs']} runs ({failed or 'none failed'}): "
        "linear / non-linear index"
    )
    table.add_column("factor")
    keys = list(res["responses"])  # those the screening reports
    for resp in keys:
        table.add_column(resp, justify="right")

    def g(v: float | None) -> str:
        return "-" if v is None else f"{v:.2f}"

    lin, non = res["linear_index"], res["nonlinear_index"]
    for f in res["factors"]:
        name = f["name"]
        table.add_row(name, *(f"{g(lin[k][name])} / {g(non[k][name])}" for k in keys))
    console = Console()
    console.print(table)
    console.print(f"results in {out}")
