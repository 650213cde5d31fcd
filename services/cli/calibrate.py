"""``scm-calib calibrate``: run a calibration study on this machine, the service's way.

The study is one of the results folder's database (:mod:`services.cli.folder_store`), made by
the calibration (or update) kind's spec and run by the service's batches and stage advance
(:func:`worker.here.run_here`), which holds its stages (the one copy); at the end, the outputs
are written (:mod:`services.cli.results`). Re-running the same
command resumes; a folder holding another study (the case, anything that changes the samples,
the datasets or the updated study differ) is refused.

``--update-of DIR --data NEW.csv`` updates the posterior of the finished study in DIR with new
datasets (paper section 5.3): stage 0 is DIR's final population, the stages temper the new
datasets' likelihood only (the old ones' is the base density), so the result targets
prior x L(old) x L(new) at a fraction of a joint study's runs; the seed is the service's
update kind's (``update_seed``: DIR's + 1), which gives the same samples bit for bit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import click
from rich.console import Console
from rich.table import Table

from scm_core.calibration import CaseDefinition, CaseError, SamplerSettings, StudyModel
from scm_core.calibration.case import field_range
from scm_core.calibration.failures import READ_MORE, reasons_text
from scm_core.calibration.report import not_a_posterior
from scm_core.inference import StageState
from scm_core.inference.tmcmc import result_of
from scm_core.inference.tmcmc.moves import MOVES, stage_chains
from scm_core.seeds import SEED_MAX
from scm_core.signals import SWTDataset
from services.limits import run_seeds
from services.stages import DatabaseStages, stage_states
from services.store import StudyRecord
from services.studies import StudyRequestError, calibration_spec
from services.studies.batching import local_batch_size
from services.studies.kinds import kind_of
from services.studies.kinds.base import stored_case
from services.studies.kinds.update import update_seed, update_spec
from worker.here import run_here

from .common import (
    CLIError,
    StudyFailed,
    as_option,
    compile_simulator_once,
    data_option,
    data_paths,
    one_line_logs,
    option_group,
    read_case,
    read_datasets,
)
from .folder_store import DB_FILE, FolderStore, open_folder_store
from .parent import ParentStudy, load_parent, stored_posterior
from .progress import StageDisplay, StageWatch, stored_walls
from .results import LegacyCheckpoints, write_outputs
from .runs import (
    POOLED_FILE,
    RUNS_FILE,
    diagnose_folders,
    print_verdict,
    run_folders,
    write_group,
)

#: most runs of one ``--runs`` group
MAX_RUNS = 64


def _with_sampler(case: CaseDefinition, sampler: dict[str, Any]) -> CaseDefinition:
    if not sampler:
        return case
    try:
        return case.with_changes(sampler=sampler)
    except CaseError as exc:
        raise CLIError(str(exc)) from None


def _update_inputs(
    parent: ParentStudy, new_paths: list[Path], max_stages: int | None
) -> tuple[CaseDefinition, list[Path], list[SWTDataset]]:
    """(the update's case, all dataset paths, all datasets: the parent's, then the new ones);
    the parent's files must still hold what it was calibrated on."""
    case = parent.case.with_changes(seed=update_seed(parent.case.seed))
    case = _with_sampler(case, {} if max_stages is None else {"max_stages": max_stages})
    old = parent.datasets()
    new = read_datasets(case, new_paths)
    for d, path in zip(new, new_paths, strict=True):
        if d.content_hash in parent.dataset_hashes:
            raise CLIError(f"--data {path}: already in the posterior of {parent.results}")
    return case, [*parent.dataset_paths, *new_paths], [*old, *new]


@dataclass(frozen=True)
class _RunOptions:
    """How a study runs here (none of it changes its results)."""

    workers: int | None
    batch_size: int | None
    no_plots: bool
    quiet: bool


@click.command()
@click.argument("case_file", required=False, type=click.Path(dir_okay=False, path_type=Path))
@data_option("SWT log or summary (repeatable); replaces the case's [data] files.")
@click.option(
    "--update-of",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Update the posterior of the finished study in this results folder with the --data "
    "datasets (no CASE_FILE: the case is that study's).",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    help="Output directory [default: ./<case file stem>_results, or <DIR>_update].",
)
@option_group(
    "options",
    _RunOptions,
    click.option(
        "--workers",
        type=click.IntRange(min=1),
        default=None,
        help="Run batches on N processes (1 numba thread each) [default: in-process, all cores].",
    ),
    click.option(
        "--batch-size",
        type=click.IntRange(min=1),
        default=None,
        help="Chains per batch (does not change the results).",
    ),
    click.option("--no-plots", is_flag=True, help="Skip the figures."),
    click.option("--quiet", is_flag=True, help="No progress display."),
)
@click.option(
    "--moves",
    type=click.Choice(sorted(MOVES)),
    default=None,
    help="Override the case's TMCMC moves.",
)
@click.option(
    "--samples",
    type=click.IntRange(min=int(field_range(SamplerSettings, "n_samples")[0])),
    default=None,
    help="Override the samples per stage.",
)
@click.option(
    "--max-stages",
    type=click.IntRange(min=int(field_range(SamplerSettings, "max_stages")[0])),
    default=None,
    help="Stop after this many tempering stages (re-run with a larger value to go on).",
)
@click.option(
    "--seed",
    type=click.IntRange(min=0, max=SEED_MAX),
    default=None,
    help="Override the case's seed (the same seed gives the same posterior).",
)
@click.option(
    "--runs",
    type=click.IntRange(min=1, max=MAX_RUNS),
    default=1,
    show_default=True,
    help="Independent runs with the seeds seed, seed + 1, ... into OUT/run_1 ...; then their "
    "R-hat, ESS, pooled posterior and a convergence verdict (OUT/runs.json).",
)
def calibrate(
    case_file: Path | None,
    data: tuple[Path, ...],
    update_of: Path | None,
    out: Path | None,
    options: _RunOptions,
    moves: str | None,
    samples: int | None,
    max_stages: int | None,
    seed: int | None,
    runs: int,
) -> None:
    """Calibrate the case CASE_FILE (TOML) against SWT datasets with TMCMC, or update the
    posterior of an earlier study with new datasets (--update-of DIR --data NEW.csv).

    Interrupt with Ctrl-C and re-run the same command to resume from the last finished stage.
    """
    parent = None
    if update_of is not None:
        if case_file is not None:
            raise CLIError("--update-of takes the case from that study; give no CASE_FILE")
        if moves is not None or samples is not None:
            raise CLIError(
                "--update-of keeps the earlier study's sampler; --moves and --samples cannot "
                "change it"
            )
        if seed is not None:
            raise CLIError("--update-of seeds the update from the earlier study; drop --seed")
        if not data:
            raise CLIError("--update-of needs the new datasets: give --data NEW.csv")
        if runs > 1:
            raise CLIError("--runs repeats a calibration; an update (--update-of) is one study")
        parent = load_parent(update_of)
        case, paths, datasets = _update_inputs(parent, list(data), max_stages)
        n_old = len(parent.dataset_paths)
    else:
        if case_file is None:
            raise CLIError("missing CASE_FILE (or --update-of DIR to update a finished study)")
        case = read_case(case_file)
        if seed is not None and seed != case.seed:
            try:
                case = case.with_changes(seed=seed)
            except CaseError as exc:
                raise CLIError(f"--seed: {exc}") from None
        case = _with_sampler(
            case,
            {
                k: v
                for k, v in (("moves", moves), ("n_samples", samples), ("max_stages", max_stages))
                if v is not None
            },
        )
        paths = data_paths(case, data)
        datasets = read_datasets(case, paths)
        n_old = 0
    model = StudyModel(case, datasets)
    if out is None:
        out = Path(f"{update_of.name}_update" if update_of else f"{case_file.stem}_results")
    if runs == 1:
        study = _Study(case, model, datasets, paths, parent, n_old)
        status = _run_study(study, out, options)
        if status == "stalled":
            raise SystemExit(1)
        return
    _run_group(_Study(case, model, datasets, paths), out, runs, options)


@dataclass(frozen=True)
class _Study:
    """What a study runs on: its case, likelihood model, datasets and their files; for an
    update, the earlier study and how many of the datasets (the first) were its."""

    case: CaseDefinition
    model: StudyModel
    datasets: list[SWTDataset]
    paths: list[Path]
    parent: ParentStudy | None = None
    n_old: int = 0

    def with_seed(self, seed: int) -> _Study:
        return replace(self, case=self.case.with_changes(seed=seed))


def _run_study(study: _Study, out: Path, options: _RunOptions) -> str:
    """Run (or resume) one study into the results folder ``out``; returns its status."""
    case, parent = study.case, study.parent
    settings = case.tmcmc_settings()
    bs = (
        options.batch_size
        or case.sampler.batch_size
        or local_batch_size(stage_chains(case.sampler.n_samples, settings), options.workers)
    )
    console = Console(stderr=True)
    with open_folder_store(out, options.workers) as folder:
        legacy = LegacyCheckpoints(out, case, study.datasets, parent.identity if parent else None)
        record = _folder_study(folder, study, bs, legacy.load(), console, options.quiet)
        done = DatabaseStages(folder.store, record.id).count()
        if not options.quiet:
            _announce(console, study, done, out, options.workers)
        compile_simulator_once(options.quiet)
        t0 = time.perf_counter()
        record, timed = _sample(folder, record, done, console, options)
        if record.status == "failed":
            raise StudyFailed(f"the study failed: {record.error}")
        run = kind_of(record.kind).build(folder.store, record)
        # stages stored before the lateral force (three responses per dataset) read with Fy NaN
        states = [run.stored(s) for s in stage_states(DatabaseStages(folder.store, record.id))]
        status = run.tempering.next(states[-1]).status or ""
    result = result_of(states, case.parameter_names, status)
    stored = stored_walls(folder.store, record)
    walls = [timed.get(i, stored[i]) for i in range(len(states))]
    extra = {
        "batch_size": bs,
        "workers": options.workers,
        "session_wall_time_s": time.perf_counter() - t0,
    }
    return _finish(study, out, result, walls, extra, options, record.id)


def _folder_study(
    folder: FolderStore,
    study: _Study,
    batch_size: int,
    earlier: list[StageState],
    console: Console,
    quiet: bool,
) -> StudyRecord:
    """The study of the results folder: the one it holds (to resume, or done), else a new
    one, which takes over the stages of the folder's checkpoints (a folder written before
    folders held a database) or of the folder's study stopped at a smaller ``max_stages`` (a larger
    one goes on from there)."""
    store, n_old = folder.store, study.n_old
    ids = folder.add_datasets(study.datasets[n_old:], study.paths[n_old:])
    try:
        if study.parent is not None:
            parent = stored_posterior(folder, study.parent, datasets=study.datasets[:n_old])
            spec = update_spec(
                store,
                folder.settings,
                parent.id,
                ids,
                batch_size=batch_size,
                max_stages=study.case.sampler.max_stages,
            )
        else:
            spec = calibration_spec(store, folder.settings, study.case, ids, batch_size)
    except StudyRequestError as exc:
        raise CLIError(as_option(str(exc), _OPTIONS)) from None
    what = "an update" if study.parent is not None else "a calibration"
    found = folder.find(spec, what)
    if found is not None and not _goes_on(found, study.case):
        return found
    record = store.studies.create(spec)
    if found is not None:
        earlier = stage_states(DatabaseStages(store, found.id))
    if earlier:
        if not quiet:
            console.print(f"taking over stages 0-{earlier[-1].stage} of {folder.out}")
        kind_of(record.kind).build(store, record).adopt(store, record, earlier)
    return store.studies.get(record.id)


def _goes_on(found: StudyRecord, case: CaseDefinition) -> bool:
    """Whether the folder's study ``found`` is taken over by a new one: it failed (its
    stages are kept), or stopped at a ``max_stages`` smaller than the case's."""
    if found.status == "failed":
        return True
    stopped = found.status == "stalled" and "max_stages" in (found.error or "")
    return stopped and stored_case(found.case).sampler.max_stages < case.sampler.max_stages


#: the study service's request fields, as this command's options
_OPTIONS = {
    "dataset_ids": "--data",
    "n_samples": "--samples",
    "max_stages": "--max-stages",
    "batch_size": "--batch-size",
    "seed": "--seed",
    "update_of": "--update-of",
}


def _announce(console: Console, study: _Study, done: int, out: Path, workers: int | None) -> None:
    case, parent = study.case, study.parent
    if done:
        console.print(f"resuming {case.name} from stage {done - 1} ({out / DB_FILE})")
        return
    what = f"update of {parent.results} with" if parent else f"{len(case.parameters)} parameters,"
    console.print(
        f"{case.name}: {what} {len(study.datasets) - study.n_old} dataset(s), "
        f"{case.sampler.n_samples} samples per stage, moves {case.tmcmc_settings().moves}, "
        f"{'in-process' if workers is None else f'{workers} worker processes'}"
    )


def _sample(
    folder: FolderStore,
    record: StudyRecord,
    done: int,
    console: Console,
    options: _RunOptions,
) -> tuple[StudyRecord, dict[int, float]]:
    """Run the folder's study to its end with the progress display (stages from ``done``
    on are shown as they finish); returns it and the wall times [s] of the stages finished
    here. Ctrl-C stops it (exit 130) keeping every stage and batch run."""
    display = StageDisplay(options.quiet, console)
    watch = StageWatch(display, done)
    try:
        with display, one_line_logs():
            record = run_here(folder.store, record.id, folder.settings, options.workers, watch)
            return record, watch.walls
    except KeyboardInterrupt:
        n = DatabaseStages(folder.store, record.id).count()
        saved = f"stages 0-{n - 1}" if n else "no finished stage"
        click.echo(
            f"interrupted: {saved} kept in {folder.out / DB_FILE}; re-run the same command to "
            "resume",
            err=True,
        )
        raise SystemExit(130) from None


def _finish(
    study: _Study,
    out: Path,
    result: Any,
    wall_times: list[float],
    extra: dict[str, Any],
    options: _RunOptions,
    study_id: int,
) -> str:
    """Write the results folder, print the summary and any warning; returns the status."""
    parent = study.parent
    sections: dict[str, Any] = {"study": {"database": DB_FILE, "id": study_id}}
    if parent is not None:
        increment = float(result.log_evidence)
        sections["update"] = {
            "update_of": str(parent.results.resolve()),
            "n_old_datasets": study.n_old,
            "log_evidence_increment": increment,
            "parent_log_evidence": parent.log_evidence,
            "log_evidence_total": parent.log_evidence + increment,
        }
    summary = write_outputs(
        out,
        result,
        study.case,
        study.model,
        study.datasets,
        wall_times,
        extra,
        plots=not options.no_plots,
        paths=study.paths,
        sections=sections,
    )
    if not options.quiet:
        _print_summary(summary, out)
    if result.status not in ("completed", "stalled"):
        click.echo(f"warning: {not_a_posterior(result.status, result.final.exponent)}", err=True)
    if result.status == "stalled":
        click.echo(
            "error: TMCMC stalled (the tempering exponent stopped increasing); see summary.json",
            err=True,
        )
    return result.status


def _run_group(study: _Study, out: Path, runs: int, options: _RunOptions) -> None:
    """``runs`` studies of ``study`` with the seeds seed, seed + 1, ... into ``out/run_k``
    (one after another, each on ``options.workers``), then their agreement and pooled
    posterior (:mod:`services.cli.runs`)."""
    try:
        seeds = run_seeds(study.case.seed, runs)
    except ValueError as exc:
        raise CLIError(f"--runs {runs}: {exc}") from None
    folders = run_folders(out, runs)
    console = Console(stderr=True)
    for k, (seed, folder) in enumerate(zip(seeds, folders, strict=True)):
        if not options.quiet:
            console.print(f"run {k + 1} of {runs} (seed {seed}) in {folder}")
        status = _run_study(study.with_seed(seed), folder, options)
        if status != "completed":
            raise CLIError(f"{folder}: the run ended {status!r}; no verdict over the runs")
    _, verdict = diagnose_folders(folders)
    write_group(out, folders, verdict)
    print_verdict(verdict)
    click.echo(f"pooled posterior and verdict in {out / POOLED_FILE}, {out / RUNS_FILE}")
    if not verdict.converged:
        click.echo(f"warning: the runs disagree ({', '.join(verdict.disagreeing)})", err=True)


def _print_summary(summary: dict[str, Any], out: Path) -> None:
    post = summary["posterior"]
    stopped = "" if summary["status"] == "completed" else " - NOT A POSTERIOR"
    table = Table(
        title=f"{summary['case']['name']}: {summary['status']} after {summary['n_stages']} "
        f"stages, {summary['model_runs']} model runs ({summary['failed_runs']} failed){stopped}"
    )
    n_failed = int(summary["failed_runs"])
    why = reasons_text(n_failed, summary.get("failed_by", {}))
    for col in ("parameter", "mean", "sd", "2.5 %", "97.5 %", "MAP"):
        table.add_column(col, justify="right" if col != "parameter" else "left")

    def g(v):
        return "-" if v is None else f"{v:.4g}"

    for name in summary["parameters"]:
        lo, hi = post["credible_interval_95"][name]
        table.add_row(
            name,
            g(post["mean"][name]),
            g(post["sd"][name]),
            g(lo),
            g(hi),
            g((post["map"] or {}).get(name)),
        )
    console = Console()
    console.print(table)
    if n_failed:
        console.print(
            f"{n_failed} of {summary['model_runs']} model runs failed (log L = -inf)"
            + (f": {why}" if why else "")
            + f'; what each reason means: {READ_MORE}; per stage: "stages" in '
            f"{out / 'summary.json'}"
        )
    warning = not_a_posterior(summary["status"], summary.get("final_exponent"))
    console.print(
        f"log evidence {g(summary['log_evidence'])} +- {g(summary['log_evidence_se'])}"
        f"{' (of the tempered target, not the model)' if warning else ''}; results in {out}"
    )
