"""Repeated runs of one study: their agreement (R-hat, ESS; :mod:`scm_core.calibration.
convergence`), the pooled posterior, and ``scm-calib diagnose DIR...``.

A run group's folder (``calibrate CASE --runs K --out DIR``) holds ``run_1`` ... ``run_K``
(ordinary results folders, seeds seed, seed + 1, ...), ``runs.json`` (the verdict, per-parameter
R-hat, bulk and tail ESS, pooled and per-run means, the runs' log evidences) and
``posterior_pooled.csv`` (every run's posterior samples, a ``run`` column first; paper Fig. 9).
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import click
import numpy as np
from rich.console import Console
from rich.table import Table

from scm_core.calibration import CaseDefinition
from scm_core.calibration.convergence import RunsVerdict, diagnose_runs
from scm_core.calibration.report import not_a_posterior
from scm_core.inference.posterior import map_sample

from .common import CLIError
from .results import load_results, read_population, write_json

RUNS_FILE = "runs.json"
POOLED_FILE = "posterior_pooled.csv"


def run_folders(out: Path, runs: int) -> list[Path]:
    """The folders of a group's runs: ``out/run_1`` ... ``out/run_K``."""
    return [out / f"run_{k + 1}" for k in range(runs)]


def group_folders(path: Path) -> list[Path] | None:
    """The run folders of a run group's folder (``calibrate --runs K --out PATH``: its
    ``runs.json``), or None when ``path`` is not one."""
    doc = path / RUNS_FILE
    if not doc.is_file():
        return None
    try:
        runs = int(json.loads(doc.read_text(encoding="utf-8"))["runs"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CLIError(f"{doc}: unreadable run group ({exc})") from None
    return run_folders(path, runs)


def expand_groups(folders: Sequence[Path]) -> list[Path]:
    """``folders`` with every run group's folder replaced by its runs' folders."""
    out: list[Path] = []
    for folder in folders:
        out.extend(group_folders(folder) or [folder])
    return out


def pooled_posterior(
    folders: Sequence[Path],
) -> tuple[CaseDefinition, np.ndarray, dict[str, float]]:
    """(case, every run's posterior samples stacked, the MAP sample of them all by name) of
    the runs of one study (:func:`diagnose_folders` checks that they are)."""
    case, _ = diagnose_folders(folders)
    names = list(case.parameter_names)
    parts = [read_population(f / "posterior.csv", names) for f in folders]
    samples = np.concatenate([p[0] for p in parts])
    best, _ = map_sample(
        samples, np.concatenate([p[2] for p in parts]), np.concatenate([p[1] for p in parts])
    )
    return case, samples, dict(zip(names, map(float, best), strict=True))


def _same_study(case: CaseDefinition) -> str:
    """The fingerprint of a case apart from its seed."""
    return case.with_changes(seed=0).fingerprint()


def diagnose_folders(folders: Sequence[Path]) -> tuple[CaseDefinition, RunsVerdict]:
    """(the case of the first run, the runs' agreement) of results folders of one study with
    different seeds; CLIError naming the folder for anything else."""
    if len(folders) < 2:
        raise CLIError("diagnose needs the results folders of at least two runs")
    cases, samples, z, se, seeds = [], [], [], [], {}
    for folder in folders:
        case, pop, summary = load_results(folder)
        status = str(summary.get("status"))
        if status != "completed":
            why = not_a_posterior(status, summary.get("final_exponent"))
            raise CLIError(f"{folder}: {why}; finish it (re-run its command) before comparing runs")
        if cases and _same_study(case) != _same_study(cases[0]):
            raise CLIError(
                f"{folder}: another study than {folders[0]} (the case, its priors or sampler "
                "differ, not only the seed)"
            )
        if case.seed in seeds:
            raise CLIError(f"{folder}: the same seed {case.seed} as {seeds[case.seed]}")
        seeds[case.seed] = folder
        cases.append(case)
        samples.append(pop)
        z.append(float(summary["log_evidence"]))
        se.append(float(summary.get("log_evidence_se") or 0.0))
    try:
        verdict = diagnose_runs(cases[0].parameter_names, samples, z, se)
    except ValueError as exc:
        raise CLIError(f"{', '.join(map(str, folders))}: {exc}") from None
    return cases[0], verdict


def write_group(out: Path, folders: Sequence[Path], verdict: RunsVerdict) -> None:
    """``runs.json`` and ``posterior_pooled.csv`` of the runs in ``folders`` under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    doc = {
        "format": "scm-calib-runs",
        "version": 1,
        "folders": [str(f.resolve()) for f in folders],
        **verdict.to_dict(),
    }
    write_json(out / RUNS_FILE, doc, indent=2)
    header_row: list[str] | None = None
    with (out / POOLED_FILE).open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        for k, folder in enumerate(folders, start=1):
            with (folder / "posterior.csv").open(newline="", encoding="utf-8") as src:
                rows = csv.reader(src)
                header = next(rows)
                if header_row is None:
                    header_row = header
                    writer.writerow(["run", *header])
                for row in rows:
                    writer.writerow([k, *row])


def print_verdict(verdict: RunsVerdict, console: Console | None = None) -> None:
    """The per-parameter table and the verdict line."""
    table = Table(title=f"agreement of {verdict.runs} runs ({verdict.draws_per_run} samples each)")
    for col in ("parameter", "R-hat", "ESS bulk", "ESS tail", "pooled mean", "pooled sd"):
        table.add_column(col, justify="left" if col == "parameter" else "right")
    table.add_column("run means", justify="left")
    for p in verdict.parameters:
        flag = "" if p.name not in verdict.disagreeing else " !"
        table.add_row(
            p.name,
            f"{p.rhat:.3f}{flag}",
            f"{p.ess_bulk:.0f}",
            f"{p.ess_tail:.0f}",
            f"{p.mean:.4g}",
            f"{p.sd:.4g}",
            " ".join(f"{m:.4g}" for m in p.run_means),
        )
    console = console or Console()
    console.print(table)
    z = ", ".join(
        f"{a:.3f} +- {b:.3f}"
        for a, b in zip(verdict.log_evidence, verdict.log_evidence_se, strict=True)
    )
    console.print(f"log evidence of the runs: {z}")
    console.print(verdict.line())


@click.command()
@click.argument(
    "folders", nargs=-1, required=True, type=click.Path(file_okay=False, path_type=Path)
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help=f"Also write {RUNS_FILE} and {POOLED_FILE} (the pooled posterior) to this folder.",
)
def diagnose(folders: tuple[Path, ...], out: Path | None) -> None:
    """Do the runs in the results FOLDERS (one study, different seeds; a `calibrate --runs`
    group's folder stands for its runs) agree? Prints per
    parameter the rank-normalised split R-hat and the bulk and tail ESS across the runs
    (ArviZ; each run's posterior a chain), and a verdict; exit status 1 when they disagree
    (an R-hat above 1.01).
    """
    for folder in folders:
        if not folder.is_dir():
            raise CLIError(f"{folder}: no such results folder")
    _, verdict = diagnose_folders(expand_groups(folders))
    print_verdict(verdict)
    if out is not None:
        write_group(out, list(folders), verdict)
        click.echo(f"wrote {out / RUNS_FILE} and {out / POOLED_FILE}")
    if not verdict.converged:
        raise SystemExit(1)
