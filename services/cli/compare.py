"""``scm-calib compare``: model classes ranked by log evidence over repeated runs, Bayes factors
with their uncertainty and a verdict in words (:mod:`scm_core.calibration.comparison`).

Each source is a case file, calibrated ``--runs`` times into ``OUT/<case file stem>`` (a run
group, as ``calibrate CASE --runs K``; re-running resumes it), or the results folder of a
finished calibration: a run group (its runs) or a single run (its reported standard error, said
as such). Writes ``OUT/compare.json``.
"""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console
from rich.table import Table

from scm_core.calibration.comparison import Comparison, ModelEvidence, compare_models
from scm_core.calibration.report import not_a_posterior

from .common import CLIError
from .results import load_summary, write_json
from .runs import expand_groups

COMPARE_FILE = "compare.json"


def model_evidence(folder: Path, name: str | None = None) -> ModelEvidence:
    """The runs of the calibration in ``folder`` (a run group or one run) as a model class
    named ``name`` (default: its case's name); CLIError naming the folder if a run is not a
    finished calibration."""
    z, se, case_name = [], [], None
    for run in expand_groups([folder]):
        case, summary = load_summary(run)
        status = str(summary.get("status"))
        if status != "completed":
            why = not_a_posterior(status, summary.get("final_exponent"))
            raise CLIError(f"{run}: {why}; finish it (re-run its command) before comparing")
        if summary.get("log_evidence") is None:
            raise CLIError(f"{run}: its summary has no log evidence")
        case_name = case_name or case.name
        z.append(float(summary["log_evidence"]))
        se.append(float(summary.get("log_evidence_se") or 0.0))
    return ModelEvidence(name or case_name or folder.name, tuple(z), tuple(se))


def _calibrated(ctx: click.Context, case_file: Path, out: Path, runs: int, workers, quiet):
    """Run (or resume) ``runs`` calibrations of ``case_file`` into ``out`` via `calibrate`."""
    from .calibrate import calibrate

    ctx.invoke(
        calibrate,
        case_file=case_file,
        out=out,
        runs=runs,
        workers=workers,
        batch_size=None,
        no_plots=True,
        quiet=quiet,
    )
    return out


def _table(comparison: Comparison) -> Table:
    table = Table(title="model classes by log evidence (mean of the runs' ln Z, se from spread)")
    for col in ("rank", "model class", "runs", "ln Z", "se", "spread", "ln B (best over it)"):
        table.add_column(col, justify="left" if col == "model class" else "right")
    table.add_column("verdict")
    by_name = {bf.worse: bf for bf in comparison.against_best}
    for rank, m in enumerate(comparison.models, start=1):
        bf = by_name.get(m.name)
        spread = "one run" if m.runs < 2 else f"{m.spread:.2f}"
        table.add_row(
            str(rank),
            m.name,
            str(m.runs),
            f"{m.mean:.2f}",
            f"{m.se:.2f}",
            spread,
            "" if bf is None else f"{bf.log_bf:.2f} +- {bf.se:.2f}",
            "best" if bf is None else ("decided" if bf.decided else "not decided"),
        )
    return table


@click.command()
@click.argument("sources", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))
@click.option(
    "--runs",
    type=click.IntRange(min=2, max=64),
    default=3,
    show_default=True,
    help="Runs of each CASE file (seeds seed, seed + 1, ...); results folders keep theirs.",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("compare_results"),
    show_default=True,
    help="Folder of the case files' run groups and compare.json.",
)
@click.option("--workers", type=click.IntRange(min=1), default=None, help="Processes per run.")
@click.option("--quiet", is_flag=True, help="No per-stage progress of the runs.")
@click.pass_context
def compare(
    ctx: click.Context,
    sources: tuple[Path, ...],
    runs: int,
    out: Path,
    workers: int | None,
    quiet: bool,
) -> None:
    """Compare model classes by their log evidence over repeated runs: each SOURCE is a case
    file (TOML, calibrated --runs times into OUT/<file stem>) or the results folder of a
    finished calibration (a `calibrate --runs K` group, or one run). Prints the classes ranked,
    the best one's Bayes factor over each other with its uncertainty and the verdict in words
    (Kass & Raftery 1995), and writes OUT/compare.json."""
    if len(sources) < 2:
        raise CLIError("compare needs at least two sources (case files or results folders)")
    folders: list[Path] = []
    for src in sources:
        if src.is_file():
            if src.suffix != ".toml":
                raise CLIError(f"{src}: not a case file (.toml) or a results folder")
            folders.append(_calibrated(ctx, src, out / src.stem, runs, workers, quiet))
        else:
            folders.append(src)
    models = [model_evidence(f) for f in folders]
    names = [m.name for m in models]
    if len(set(names)) != len(names):  # two folders of one case: name them by their folders
        models = [model_evidence(f, name=str(f)) for f in folders]
    try:
        comparison = compare_models(models)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    console = Console()
    console.print(_table(comparison))
    for line in comparison.lines():
        console.print(line, highlight=False)
    single = [m.name for m in comparison.models if m.runs < 2]
    if single:
        console.print(
            f"{', '.join(single)}: one run, so its own reported standard error, which can "
            "understate a run's error many times on a slowly mixing case; calibrate --runs 3 "
            "or more for an error from the runs' spread",
            highlight=False,
        )
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / COMPARE_FILE, comparison.to_dict(), indent=2)
    console.print(f"written: {out / COMPARE_FILE}", highlight=False)
