"""``scm-calib calibrate``: run a calibration study on this machine, with checkpoints.

Output directory layout::

    DIR/checkpoints/manifest.json      what the checkpoints belong to (case and data hashes)
    DIR/checkpoints/stage_NNN.json     StageState.to_dict() of each finished stage + wall time
    DIR/samples/stage_NN.csv           samples of every stage: parameters, log_likelihood,
                                       log_prior, simulated responses F/T/z per dataset
    DIR/posterior.csv                  the final stage's samples (same columns)
    DIR/summary.json                   posterior summary, evidence, diagnostics, settings
    DIR/figures/prior_posterior.png    Figure 5-like
    DIR/figures/posterior_pairs.png    Figures 6-8-like
    DIR/figures/fit_map.png            measured vs simulated at the MAP sample (Figure 3-like)

Re-running the same command resumes from the last finished stage; the checkpoints are refused
if the case (anything that changes the samples) or the datasets differ.
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import click
import numpy as np
from pydantic import ValidationError
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from scm_core.calibration import (
    CaseDefinition,
    CaseError,
    StageStart,
    StudyModel,
    run_tmcmc,
    study_summary,
)
from scm_core.calibration.report import finite_or_none
from scm_core.inference import StageState, TMCMCResult
from scm_core.signals import SWTDataset

from .common import CLIError, data_option, data_paths, read_case, read_datasets
from .pool import batch_map

CHECKPOINT_FORMAT = "scm-calib-checkpoints"


# ---------------------------------------------------------------------- checkpoints


def _write_json(path: Path, doc: Any) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(doc, separators=(",", ":")), encoding="utf-8")
    os.replace(tmp, path)


class Checkpoints:
    """Stage states of one study under DIR/checkpoints (atomic writes)."""

    def __init__(self, out: Path, case: CaseDefinition, datasets: Sequence[SWTDataset]):
        self.dir = out / "checkpoints"
        self.manifest = {
            "format": CHECKPOINT_FORMAT,
            "version": 1,
            "case": case.name,
            "case_hash": case.fingerprint(),
            "data_hashes": [d.content_hash for d in datasets],
            "parameters": list(case.parameter_names),
            "n_samples": case.sampler.n_samples,
            "seed": case.seed,
        }

    def load(self) -> tuple[list[StageState], list[float]]:
        """Saved stages (consecutive from 0) and their wall times; refuses a different study."""
        path = self.dir / "manifest.json"
        if not path.is_file():
            return [], []
        try:
            saved = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise CLIError(f"{path}: unreadable checkpoint manifest ({exc})") from None
        if saved.get("format") != CHECKPOINT_FORMAT:
            raise CLIError(f"{path}: not a scm-calib checkpoint manifest")
        what = []
        if saved.get("case_hash") != self.manifest["case_hash"]:
            what.append("the case (priors, nominal values, simulator or sampler settings)")
        if saved.get("data_hashes") != self.manifest["data_hashes"]:
            what.append("the datasets")
        if what:
            raise CLIError(
                f"{self.dir} holds checkpoints of another study: {' and '.join(what)} changed "
                "since; use another --out directory or delete the checkpoints to start over"
            )
        stages: list[StageState] = []
        walls: list[float] = []
        while (p := self.dir / f"stage_{len(stages):03d}.json").is_file():
            try:
                doc = json.loads(p.read_text(encoding="utf-8"))
                stages.append(StageState.from_dict(doc["state"]))
            except (OSError, json.JSONDecodeError, KeyError, ValueError, TypeError) as exc:
                raise CLIError(f"{p}: unreadable checkpoint ({exc})") from None
            walls.append(float(doc.get("wall_time_s", 0.0)))
        return stages, walls

    def start(self, fresh: bool) -> None:
        """Write the manifest; a fresh study first drops stage files left without one."""
        self.dir.mkdir(parents=True, exist_ok=True)
        if fresh:
            for old in self.dir.glob("stage_*.json"):
                old.unlink()
        _write_json(self.dir / "manifest.json", self.manifest)

    def save(self, state: StageState, wall_time_s: float) -> None:
        doc = {"state": state.to_dict(), "wall_time_s": wall_time_s}
        _write_json(self.dir / f"stage_{state.stage:03d}.json", doc)


# ---------------------------------------------------------------------- outputs


def _fmt(v: float) -> str:
    return "nan" if not math.isfinite(v) else repr(float(v))


def write_stage_csv(
    path: Path, state: StageState, names: Sequence[str], response_names: Sequence[str]
) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        resp = state.responses
        header = [*names, "log_likelihood", "log_prior"]
        if resp is not None:
            header += list(response_names)
        w.writerow(header)
        for i in range(state.n_samples):
            row = [_fmt(v) for v in state.samples[i]]
            row += [_fmt(state.log_likelihood[i]), _fmt(state.log_prior[i])]
            if resp is not None:
                row += [_fmt(v) for v in resp[i]]
            w.writerow(row)


def _mean_b_eff(sim) -> float | None:
    if sim is None:
        return None
    b = sim.series["b_eff"]
    t = sim.series["t"]
    sel = b[(t >= t[-1] / 2) & (b > 0)]
    return float(sel.mean()) if sel.size else None


def write_outputs(
    out: Path,
    result: TMCMCResult,
    case: CaseDefinition,
    model: StudyModel,
    datasets: Sequence[SWTDataset],
    wall_times: Sequence[float],
    extra_settings: dict[str, Any],
    plots: bool = True,
) -> dict[str, Any]:
    """Stage CSVs, posterior.csv, summary.json and the figures; returns the summary."""
    samples_dir = out / "samples"
    samples_dir.mkdir(parents=True, exist_ok=True)
    for old in samples_dir.glob("stage_*.csv"):  # left by an earlier study in this directory
        old.unlink()
    names = result.names
    for st in result.stages:
        write_stage_csv(samples_dir / f"stage_{st.stage:02d}.csv", st, names, model.response_names)
    write_stage_csv(out / "posterior.csv", result.final, names, model.response_names)

    # the MAP sample's simulations, for the fit figure and the summary
    lp = result.final.log_prior + result.final.log_likelihood
    theta = result.final.samples[int(np.argmax(np.where(np.isnan(lp), -np.inf, lp)))]
    sims, map_responses = [], {}
    offsets = model.measurement_offsets(theta)
    for k, ds in enumerate(datasets):
        try:
            sim = model.simulate_at(theta, k)
        except (ValidationError, ValueError):
            sim = None
        sims.append(sim)
        m = sim.means if sim is not None else None
        map_responses[ds.name] = {
            "status": None if sim is None else sim.status,
            "simulated": {
                r: finite_or_none(getattr(m, r) + offsets.get(r, 0.0)) if m else None for r in "FTz"
            },
            "measured": {r: float(ds.responses[r].mean) for r in "FTz" if r in ds.responses},
        }
    summary = study_summary(result, case, model, wall_times, extra_settings, map_responses)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")

    if plots:
        from services.plots.fit import plot_fit
        from services.plots.posterior import plot_pairs, plot_prior_posterior

        fig_dir = out / "figures"
        fig_dir.mkdir(exist_ok=True)
        prior = case.prior()
        units = dict(prior.units or {})
        log_params = {n for n, d in prior.dists.items() if d.kind == "log_uniform"}
        plot_prior_posterior(
            names,
            result.stages[0].samples,
            result.samples,
            fig_dir / "prior_posterior.png",
            bounds=prior.bounds,
            units=units,
            map_sample=theta,
            reference=case.reference,
            title=f"{case.name}: prior and posterior ({result.status})",
            log_params=log_params,
        )
        b_eff = _mean_b_eff(sims[0])
        k_star = case.reference.get("k_star")
        plot_pairs(
            names,
            result.samples,
            fig_dir / "posterior_pairs.png",
            units=units,
            reference=case.reference,
            k_star_line=(k_star, b_eff) if k_star and b_eff else None,
            title=f"{case.name}: bivariate posterior densities",
            log_params=log_params,
        )
        plot_fit(
            datasets,
            sims,
            fig_dir / "fit_map.png",
            title=f"{case.name}: measured vs simulated at the MAP sample",
            responses=case.responses,
            offsets=model.measurement_offsets(theta),
        )
    return summary


# ---------------------------------------------------------------------- progress


class _Display:
    """Progress of the stages: a rich bar per stage (stage, exponent, evaluations done/planned,
    ETA) on a terminal; otherwise (a log file, a pipe) plain lines, one every 10 % of a stage
    and one per finished stage, flushed at once."""

    def __init__(self, quiet: bool, console: Console | None = None):
        self.quiet = quiet
        self.console = console or Console(stderr=True)
        self.lines = not self.console.is_terminal
        self.progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("evaluations"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=self.console,
            disable=quiet or self.lines,
        )
        self.task = None
        self.total = 1
        self.done = 0
        self.next_tenth = 1
        self.stage = 0
        self.t0 = time.perf_counter()

    def __enter__(self):
        self.progress.__enter__()
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def _line(self, text: str) -> None:
        if not self.quiet:
            print(text, file=self.console.file, flush=True)

    def stage_start(self, s: StageStart) -> None:
        self.total = max(s.planned, 1)
        self.done = 0
        self.next_tenth = 1
        self.stage = s.stage
        self.t0 = time.perf_counter()
        if self.lines:
            self._line(
                f"stage {s.stage:2d} started: p = {s.exponent:.4g}, {s.planned} evaluations planned"
            )
            return
        desc = f"stage {s.stage:2d}  p = {s.exponent:.4g}"
        if self.task is not None:
            self.progress.update(self.task, visible=False)
        self.task = self.progress.add_task(desc, total=self.total)

    def batch(self, k: int) -> None:
        self.done += k
        if not self.lines:
            if self.task is not None:
                self.progress.advance(self.task, k)
            return
        crossed = False
        while self.next_tenth <= 9 and self.done * 10 >= self.next_tenth * self.total:
            self.next_tenth += 1  # a batch that crosses several tenths gives one line
            crossed = True
        if crossed and self.done < self.total:  # the stage's end has its own line
            elapsed = time.perf_counter() - self.t0
            frac = self.done / self.total
            eta = elapsed * (1 - frac) / frac
            self._line(
                f"stage {self.stage:2d}: {int(100 * frac):3d} % ({self.done}/{self.total} "
                f"evaluations), {elapsed:.0f} s elapsed, ETA {eta:.0f} s"
            )

    def stage_done(self, state: StageState, wall: float) -> None:
        if self.task is not None:
            self.progress.update(self.task, completed=self.total)
        if not self.quiet:
            rate = state.acceptance_rate
            acc = f"{rate:.2f}" if math.isfinite(rate) else "-"
            text = (
                f"stage {state.stage:2d} done: p = {state.exponent:.4g}, acceptance {acc}, "
                f"ESS {state.ess:.0f}, unique {state.n_unique}, model runs {state.model_runs}, "
                f"failed {state.failed_runs}, {wall:.1f} s"
            )
            if self.lines:
                self._line(text)
            else:
                self.progress.console.print(text)


# ---------------------------------------------------------------------- Ctrl-C


class _StopRequest:
    """SIGINT handler for the run: the first Ctrl-C asks to stop at the next safe point (the
    next simulator call or returned batch, see :meth:`check`); a second one raises at once."""

    def __init__(self, console: Console | None):
        self.console = console
        self.requested = False
        self._previous: Any = None

    def _handler(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        if self.console is not None:
            self.console.print("stopping at the next safe point (Ctrl-C again to abort now)")

    def check(self) -> None:
        if self.requested:
            raise KeyboardInterrupt

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


class _Checked:
    """The model's batch likelihood, refusing to start while a stop is requested."""

    def __init__(self, stop: _StopRequest, model: StudyModel):
        self.stop = stop
        self.model = model

    def __call__(self, X):
        self.stop.check()
        return self.model.log_likelihood_batch(X)


def _is_interrupt(exc: BaseException | None) -> bool:
    """KeyboardInterrupt, possibly wrapped (numba turns one raised while it unpickles a result
    into a SystemError whose cause is the KeyboardInterrupt)."""
    seen = 0
    while exc is not None and seen < 10:
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc = exc.__cause__ or exc.__context__
        seen += 1
    return False


# ---------------------------------------------------------------------- command


def _default_batch_size(n_samples: int, workers: int | None) -> int:
    parts = 4 if workers is None else 4 * workers
    return max(1, math.ceil(n_samples / parts))


def _precheck(case: CaseDefinition, model: StudyModel) -> None:
    """Refuse a study whose configuration cannot be built at the prior medians."""
    theta = case.prior().ppf(np.full(len(case.parameters), 0.5))
    problem = model.config_problem(theta)
    if problem is not None:
        k, why = problem
        raise CLIError(f"dataset {model.datasets[k].name}: {why}")


@click.command()
@click.argument("case_file", type=click.Path(dir_okay=False, path_type=Path))
@data_option("SWT log or summary (repeatable); replaces the case's [data] files.")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    help="Output directory [default: ./<case file stem>_results].",
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Run batches on N processes (1 numba thread each) [default: in-process, all cores].",
)
@click.option(
    "--moves",
    type=click.Choice(["leader", "resample-move"]),
    default=None,
    help="Override the case's TMCMC moves.",
)
@click.option(
    "--samples", type=click.IntRange(min=10), default=None, help="Override the samples per stage."
)
@click.option(
    "--max-stages",
    type=click.IntRange(min=1),
    default=None,
    help="Stop after this many tempering stages (re-run with a larger value to go on).",
)
@click.option(
    "--batch-size",
    type=click.IntRange(min=1),
    default=None,
    help="Chains per batch (does not change the results).",
)
@click.option("--no-plots", is_flag=True, help="Skip the figures.")
@click.option("--quiet", is_flag=True, help="No progress display.")
def calibrate(
    case_file: Path,
    data: tuple[Path, ...],
    out: Path | None,
    workers: int | None,
    moves: str | None,
    samples: int | None,
    max_stages: int | None,
    batch_size: int | None,
    no_plots: bool,
    quiet: bool,
) -> None:
    """Calibrate the case CASE_FILE (TOML) against SWT datasets with TMCMC.

    Interrupt with Ctrl-C and re-run the same command to resume from the last finished stage.
    """
    case = read_case(case_file)
    sampler = {
        k: v
        for k, v in (("moves", moves), ("n_samples", samples), ("max_stages", max_stages))
        if v is not None
    }
    if sampler:
        try:
            case = case.with_changes(sampler=sampler)
        except CaseError as exc:
            raise CLIError(str(exc)) from None
    datasets = read_datasets(case, data_paths(case, data))
    model = StudyModel(case, datasets)
    _precheck(case, model)
    prior = case.prior()
    settings = case.tmcmc_settings()
    n = case.sampler.n_samples
    bs = batch_size or case.sampler.batch_size or _default_batch_size(n, workers)

    out = out or Path(f"{case_file.stem}_results")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"--out {out}: {exc.strerror or exc}") from None
    ckpt = Checkpoints(out, case, datasets)
    stages, walls = ckpt.load()
    ckpt.start(fresh=not stages)

    console = Console(stderr=True)
    if stages and not quiet:
        console.print(f"resuming {case.name} from stage {stages[-1].stage} ({ckpt.dir})")
    elif not quiet:
        console.print(
            f"{case.name}: {len(case.parameters)} parameters, {len(datasets)} dataset(s), "
            f"{n} samples per stage, moves {settings.moves}, "
            f"{'in-process' if workers is None else f'{workers} worker processes'}"
        )

    wall_times = list(walls)
    t_start = [time.perf_counter()]
    display = _Display(quiet, console)
    stop = _StopRequest(console if not quiet else None)

    def on_stage_start(s: StageStart) -> None:
        t_start[0] = time.perf_counter()
        display.stage_start(s)

    def on_stage(state: StageState) -> None:
        wall = time.perf_counter() - t_start[0]
        ckpt.save(state, wall)
        wall_times.append(wall)
        display.stage_done(state, wall)

    def on_batch(k: int) -> None:
        stop.check()
        display.batch(k)

    # in-process, Ctrl-C is noticed before every simulator call (between Metropolis steps);
    # with workers, when a batch comes back
    func = model.log_likelihood_batch if workers is not None else _Checked(stop, model)
    t0 = time.perf_counter()
    try:
        with stop, display, batch_map(workers) as mapper:
            result = run_tmcmc(
                func,
                prior,
                n,
                case.seed,
                settings,
                map=mapper,
                batch_size=bs,
                resume_from=stages or None,
                on_stage_start=on_stage_start,
                on_batch=on_batch,
                on_stage=on_stage,
            )
    except BaseException as exc:
        if not _is_interrupt(exc):
            raise
        saved = f"stages 0-{len(wall_times) - 1}" if wall_times else "no finished stage"
        click.echo(
            f"interrupted: {saved} saved in {ckpt.dir}; re-run the same command to resume",
            err=True,
        )
        raise SystemExit(130) from None

    extra = {
        "batch_size": bs,
        "workers": workers,
        "session_wall_time_s": time.perf_counter() - t0,
    }
    summary = write_outputs(
        out, result, case, model, datasets, wall_times, extra, plots=not no_plots
    )
    if not quiet:
        _print_summary(summary, out)
    if result.status == "stalled":
        click.echo(
            "error: TMCMC stalled (the tempering exponent stopped increasing); see summary.json",
            err=True,
        )
        raise SystemExit(1)


def _print_summary(summary: dict[str, Any], out: Path) -> None:
    post = summary["posterior"]
    table = Table(
        title=f"{summary['case']['name']}: {summary['status']} after {summary['n_stages']} "
        f"stages, {summary['model_runs']} model runs ({summary['failed_runs']} failed)"
    )
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
    console.print(
        f"log evidence {g(summary['log_evidence'])} +- {g(summary['log_evidence_se'])}; "
        f"results in {out}"
    )
