"""``scm-calib sensitivity``: Morris screening of the soil parameters (paper section 4.4)."""

from __future__ import annotations

import math
from pathlib import Path

import click
from rich.console import Console
from rich.table import Table

from scm_core.calibration import MorrisSettings, run_sensitivity, screening_factors

from .common import CLIError, compile_simulator_once, data_paths, read_case, read_datasets
from .pool import batch_map
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
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0))
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
    test conditions of one dataset, with the case's nominal values and simulator settings."""
    case = read_case(case_file)
    if levels % 2:
        raise CLIError(f"--levels must be even, got {levels}")
    paths = [data] if data is not None else data_paths(case, ())[:1]
    dataset = read_datasets(case, paths)[0]
    given = _parse_bounds(bounds)
    try:
        names, _, _ = screening_factors(case, joint_k=not separate_k, bounds=given)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    n_runs = r * (len(names) + 1)
    compile_simulator_once()
    with batch_map(workers) as mapper:
        batch = None if workers is None else max(1, math.ceil(n_runs / (4 * workers)))
        try:
            result = run_sensitivity(
                dataset,
                case,
                MorrisSettings(r, levels, seed, not separate_k, given),
                map=mapper,
                batch_size=batch,
            )
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            raise SystemExit(130) from None
    out = out or Path(f"{case_file.stem}_sensitivity")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"--out {out}: {exc.strerror or exc}") from None
    doc = {
        "case": case.name,
        "joint_k": not separate_k,
        "dataset_hash": dataset.content_hash,
        "conditions": dataset.conditions.to_sim_config(),
        **result.to_dict(),
    }
    write_json(out / "sensitivity.json", doc, indent=2)
    from services.plots.sensitivity import plot_morris

    plot_morris(result, out / "sensitivity.png")

    table = Table(
        title=f"Morris screening, {result.n_runs} runs ({result.n_failed} failed): "
        "linear / non-linear index"
    )
    table.add_column("factor")
    for resp in ("F", "T", "z"):
        table.add_column(resp, justify="right")
    for i, name in enumerate(result.names):
        cells = [
            f"{result.linear_index[i, k]:.2f} / {result.nonlinear_index[i, k]:.2f}"
            for k in range(3)
        ]
        table.add_row(name, *cells)
    console = Console()
    console.print(table)
    console.print(f"results in {out}")
