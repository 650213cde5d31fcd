"""The accurate sampler at the paper's budget (issue 12): one table for paper case 1.

Paper case 1 (``examples/case1.toml``: k_c, k_phi, n, phi, J and the three sigmas) on the example
log at slip 0.2 (``examples/wf34_s020.csv``) with the default simulator, sampled three ways at each
``--samples`` size:

* leader: the paper's form (Ching & Chen 2007), one model run per sample and stage;
* accurate: resample-move, 10-50 Metropolis steps per sample and stage (the default form);
* accurate-log: the same with the random walk in log coordinates for the positive parameters
  (``proposal_scale = "log"``; exact, no surrogate);
* accelerated: the accurate form with surrogate transitions (``--surrogate-steps`` K Metropolis
  steps on a surrogate of the responses, fitted on each stage's starting states, then one model
  run corrects; K = 1 is Christen & Fox's delayed acceptance; ``scm_core/inference/surrogate.py``;
  exact: the chains still target the posterior);
* waste-free: the accelerated accurate form of a case with ``moves = "waste-free"`` (chains of
  P = 5 states whose moves are surrogate transitions of 40 steps, log walk, multinomial
  resampling; ``--moves``, ``--surrogate-steps``, ``--proposal-scale``, ``--resampling`` change
  it).

A one-dataset study has nothing for early rejection to cut, so it is on (the default) and idle.
Per form and size: stages, model runs, surrogate evaluations (the inner steps), moves the
surrogate turned down without a model run, wall time on ``--workers`` processes, log evidence with
its standard error, the smallest chain ESS over the parameters (waste-free: M / P x the ratio of
the population variance to the variance of chain means, Dau & Chopin 2022 section 3.4; the
population's effective size for means within its last stage), and per parameter the posterior
mean and sd and, for the other forms, the distance to the accurate form of the same size
(|difference of means| in the accurate sd, and the two-sample KS statistic).

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_study.py [--samples 500 2000] [--workers 2]
        [--forms leader accurate accelerated waste-free] [--surrogate-steps K] [--moves M]
        [--seed 1] [--proposal-scale linear|log] [--json OUT.json] [--save DIR]
        [--reference DIR [DIR ...]]
        [--reference-form accurate|accurate-log] [--resampling systematic|multinomial]

``--save DIR`` writes each run's final samples (``FORM_N.npy``); ``--reference DIR`` compares with
the accurate form's samples saved there instead of running it again (the unaccelerated form's
result does not change with the acceleration's settings); several DIRs (runs with different
seeds) are pooled into one reference, whose own run-to-run noise is then smaller.
``--reference-form`` names the unaccelerated form the others are compared with (``accurate``, or
``accurate-log``, saved as ``accurate-log_N.npy``). ``--prior-case FILE`` runs the forms with
another case (other priors) on the same log.

A whole calibration as committed (its own datasets, sampler and seed), timed as a user runs it:

    PYTHONPATH=. python benchmarks/bench_study.py --case examples/cmu_smooth.toml [--workers 2]
        [--repeats 1]

runs ``scm-calib calibrate CASE --workers W --no-plots`` (a fresh output directory per run, the
simulator compiled beforehand so that no run pays for it) and prints per run the wall time, the
stages, model runs (failed), the log evidence and the model runs per second.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.stats import ks_2samp

from scm_core.calibration import CaseDefinition, StudyModel, load_case, run_tmcmc
from scm_core.inference.tmcmc.moves import WasteFreeMove, stage_chains
from scm_core.inference.tmcmc.types import RESAMPLING
from scm_core.signals import load_dataset
from services.studies.batching import local_batch_size
from worker.batch_map import batch_map

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "case1.toml"
LOG = ROOT / "examples" / "wf34_s020.csv"
#: the unaccelerated forms name every setting; the accelerated ones take the study defaults
#: (``form_defaults``) unless an option below changes them
FORMS = {
    "leader": {"moves": "leader"},
    "accurate": {
        "moves": "resample-move",
        "delayed_acceptance": False,
        "proposal_scale": "linear",
        "resampling": "systematic",
    },
    "accurate-log": {
        "moves": "resample-move",
        "delayed_acceptance": False,
        "proposal_scale": "log",
        "resampling": "systematic",
    },
    "accelerated": {"moves": "resample-move", "delayed_acceptance": True},
    "waste-free": {"moves": "waste-free", "delayed_acceptance": True},
}


def chain_ess(samples: np.ndarray, per_chain: int) -> np.ndarray:
    """Per parameter: the effective sample size for its mean of a waste-free population of
    consecutive chains of ``per_chain`` states, M var(x) / var(chain means) with the M chains
    as the independent units (Dau & Chopin 2022, section 3.4); a trailing short chain is left
    out. It measures the last stage's chains only, not what the roots inherit."""
    m = samples.shape[0] // per_chain
    chains = samples[: m * per_chain].reshape(m, per_chain, -1).mean(axis=1)
    return m * samples.var(axis=0) / chains.var(axis=0, ddof=1)


def load_model(case: CaseDefinition) -> StudyModel:
    """The study model of ``case`` on the example log (averaged as the case says)."""
    data = load_dataset(LOG, offset=case.data.offset, cutoff_hz=case.data.cutoff_hz)
    return StudyModel(case, [data])


def run_form(
    form: str,
    n_samples: int,
    seed: int,
    workers: int,
    surrogate_steps: int | None,
    moves: int | None,
    proposal_scale: str | None = None,
    case_path: Path = CASE,
    resampling: str | None = None,
    jumps: float | None = None,
) -> dict:
    """One run of ``form``; None options keep the form's (study) defaults."""
    sampler = {"n_samples": n_samples, **FORMS[form]}
    if resampling is not None:
        sampler["resampling"] = resampling
    if sampler.get("delayed_acceptance"):  # the accelerated forms; the others as they are
        accelerated = {
            "proposal_scale": proposal_scale,
            "surrogate_steps": surrogate_steps,
            "n_steps": moves,
            "surrogate_jumps": jumps,
        }
        sampler.update({k: v for k, v in accelerated.items() if v is not None})
    case = load_case(case_path).with_changes(sampler=sampler)
    model = load_model(case)
    batch = local_batch_size(stage_chains(n_samples, case.tmcmc_settings()), workers)
    t0 = time.perf_counter()
    with batch_map(workers) as mapper:
        res = run_tmcmc(
            model,
            case.prior(),
            n_samples,
            seed,
            case.tmcmc_settings(),
            map=mapper,
            batch_size=batch,
        )
    wall = time.perf_counter() - t0
    stages = [
        {
            "stage": s.stage,
            "exponent": float(s.exponent),
            "model_runs": int(s.model_runs),
            "acceptance": float(s.acceptance_rate),
            "inner_acceptance": s.surrogate_steps_accepted / s.surrogate_steps
            if s.surrogate_steps
            else None,
            "first_stage_rejections": int(s.first_stage_rejections),
            "surrogate_error": s.surrogate_error_sum / s.surrogate_checks
            if s.surrogate_checks
            else None,
            "ess": float(s.ess),
            "distinct": int(np.unique(s.samples, axis=0).shape[0]),
            "beta": float(s.beta),
        }
        for s in res.stages
    ]
    screened = sum(s.first_stage_rejections for s in res.stages)
    settings = case.tmcmc_settings()
    per_chain = WasteFreeMove.states_per_chain(settings) if settings.moves == "waste-free" else 0
    inner = sum(s.surrogate_steps for s in res.stages)
    return {
        "form": form,
        "n_samples": n_samples,
        "status": res.status,
        "stages": len(res.stages) - 1,
        "model_runs": int(res.n_model_runs),
        "first_stage_evaluations": int(inner),
        "first_stage_rejections": int(screened),
        "wall_s": wall,
        "log_evidence": float(res.log_evidence),
        "log_evidence_se": float(res.log_evidence_se),
        "chain_ess": float(chain_ess(res.samples, per_chain).min()) if per_chain else None,
        "names": list(res.names),
        "samples": res.samples,
        "stage_rows": stages,
    }


def run_case(case: Path, workers: int, repeats: int) -> None:
    """``repeats`` whole calibrations of ``case`` as committed, through the command line."""
    subprocess.run(  # compile (or load) the simulator once, outside the timed runs
        [sys.executable, "-c", "from scm_core.simulator import simulate_swt; simulate_swt()"],
        check=True,
    )
    table = Table(title=f"{case} as committed, {workers} workers")
    for col in ("run", "status", "wall s", "stages", "model runs (failed)", "log Z", "runs/s"):
        table.add_column(col, justify="right")
    walls = []
    for k in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "results"
            cmd = [sys.executable, "-m", "services.cli", "calibrate", str(case)]
            cmd += ["--workers", str(workers), "--out", str(out), "--no-plots", "--quiet"]
            t0 = time.perf_counter()
            done = subprocess.run(cmd, check=False)
            wall = time.perf_counter() - t0
            summary = json.loads((out / "summary.json").read_text())
        walls.append(wall)
        table.add_row(
            str(k + 1),
            f"{summary['status']} (exit {done.returncode})",
            f"{wall:.0f}",
            str(summary["n_stages"]),
            f"{summary['model_runs']} ({summary['failed_runs']})",
            f"{summary['log_evidence']:.3f} +- {summary['log_evidence_se']:.3f}",
            f"{summary['model_runs'] / wall:.1f}",
        )
        print(f"run {k + 1}: {wall:.0f} s, {summary['model_runs']} model runs", flush=True)
    if repeats > 1:
        table.add_row("median", "", f"{float(np.median(walls)):.0f}", "", "", "", "")
    Console(width=160).print(table)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, nargs="+", default=[500, 2000])
    ap.add_argument("--forms", nargs="+", choices=list(FORMS), default=list(FORMS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--surrogate-steps", type=int, default=None, help="accelerated: inner steps (default 40)"
    )
    ap.add_argument(
        "--moves",
        type=int,
        default=None,
        help="accelerated: moves per chain (default: waste-free 4, resample-move adapted)",
    )
    ap.add_argument(
        "--proposal-scale",
        choices=["linear", "log"],
        default=None,
        help="random-walk coordinates of the accelerated forms (default log)",
    )
    ap.add_argument(
        "--prior-case",
        type=Path,
        default=CASE,
        help="the forms with another case on the same log (e.g. other priors)",
    )
    ap.add_argument(
        "--case",
        type=Path,
        default=None,
        help="instead of the forms: this case's whole calibration as committed (its datasets, "
        "sampler and seed) through scm-calib calibrate",
    )
    ap.add_argument("--repeats", type=int, default=1, help="--case: calibrations to run")
    ap.add_argument(
        "--resampling",
        choices=RESAMPLING,
        default=None,
        help="resampling of every form run (default: the accurate forms and leader systematic, "
        "the accelerated multinomial, which gives right log-evidence errors)",
    )
    ap.add_argument(
        "--jumps",
        type=float,
        default=None,
        help="accelerated: probability of a population jump per surrogate step (default: "
        "the form's, 0.2 for waste-free)",
    )
    ap.add_argument("--stages", action="store_true", help="also print each run's stages")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    ap.add_argument("--save", type=Path, default=None, help="write each run's samples here")
    ap.add_argument(
        "--reference", type=Path, nargs="+", default=None, help="saved accurate samples (pooled)"
    )
    ap.add_argument(
        "--reference-form",
        choices=[f for f in FORMS if f.startswith("accurate")],
        default="accurate",
        help="the unaccelerated form the others are compared with",
    )
    args = ap.parse_args()
    if args.case is not None:
        run_case(args.case, args.workers, args.repeats)
        return

    ref_form = args.reference_form
    rows = []
    for n in args.samples:
        if args.reference is not None and ref_form not in args.forms:
            ref = np.concatenate([np.load(d / f"{ref_form}_{n}.npy") for d in args.reference])
            rows.append({"form": ref_form, "n_samples": n, "samples": ref, "saved": True})
        for form in args.forms:
            rows.append(
                run_form(
                    form,
                    n,
                    args.seed,
                    args.workers,
                    args.surrogate_steps,
                    args.moves,
                    args.proposal_scale,
                    args.prior_case,
                    args.resampling,
                    args.jumps,
                )
            )
            r = rows[-1]
            if args.save is not None:
                args.save.mkdir(parents=True, exist_ok=True)
                np.save(args.save / f"{form}_{n}.npy", r["samples"])
            print(
                f"{form} {n}: {r['model_runs']} runs, {r['wall_s']:.0f} s, "
                f"log Z {r['log_evidence']:.3f}",
                flush=True,
            )
    names = next(r["names"] for r in rows if "names" in r)
    runs = Table(title=f"paper case 1 on wf34_s020, seed {args.seed}, {args.workers} workers")
    for col in ("samples", "form", "stages", "model runs", "surrogate evals", "screened out"):
        runs.add_column(col, justify="right")
    for col in ("wall s", "log Z", "chain ESS"):
        runs.add_column(col, justify="right")
    post = Table(title=f"posterior mean (sd); vs {ref_form}: |d mean| / sd_{ref_form}, KS")
    post.add_column("samples", justify="right")
    post.add_column("form")
    for name in names:
        post.add_column(name, justify="right")
    for r in rows:
        if r.get("saved"):
            runs.add_row(str(r["n_samples"]), f"{r['form']} (saved)", *["-"] * 7)
        else:
            runs.add_row(
                str(r["n_samples"]),
                r["form"],
                str(r["stages"]),
                str(r["model_runs"]),
                str(r["first_stage_evaluations"]),
                str(r["first_stage_rejections"]),
                f"{r['wall_s']:.0f}",
                f"{r['log_evidence']:.3f} +- {r['log_evidence_se']:.3f}",
                "-" if r["chain_ess"] is None else f"{r['chain_ess']:.0f}",
            )
        ref = next(
            (a for a in rows if a["form"] == ref_form and a["n_samples"] == r["n_samples"]),
            None,
        )
        cells = []
        for j in range(len(names)):
            x = r["samples"][:, j]
            cell = f"{x.mean():.4g} ({x.std(ddof=1):.3g})"
            if ref is not None and ref is not r:
                y = ref["samples"][:, j]
                d = abs(x.mean() - y.mean()) / y.std(ddof=1)
                cell += f"; {d:.3f}, {ks_2samp(x, y).statistic:.3f}"
            cells.append(cell)
        post.add_row(str(r["n_samples"]), r["form"], *cells)
    console = Console(width=220)
    console.print(runs)
    console.print(post)
    if args.stages:
        for r in rows:
            if r.get("saved"):
                continue
            st = Table(title=f"{r['form']} {r['n_samples']}: stages")
            for col in (
                "stage",
                "exponent",
                "model runs",
                "acceptance",
                "inner acc.",
                "screened out",
                "mean |log L~ - log L|",
                "ESS",
                "distinct states",
                "beta",
            ):
                st.add_column(col, justify="right")
            for s in r["stage_rows"]:
                st.add_row(
                    str(s["stage"]),
                    f"{s['exponent']:.4g}",
                    str(s["model_runs"]),
                    f"{s['acceptance']:.3f}",
                    "-" if s["inner_acceptance"] is None else f"{s['inner_acceptance']:.3f}",
                    str(s["first_stage_rejections"]),
                    "-" if s["surrogate_error"] is None else f"{s['surrogate_error']:.3g}",
                    f"{s['ess']:.0f}",
                    str(s["distinct"]),
                    f"{s['beta']:.3g}",
                )
            console.print(st)
    if args.json is not None:
        out = [{k: v for k, v in r.items() if k not in ("samples",)} for r in rows if "names" in r]
        for r, o in zip([r for r in rows if "names" in r], out, strict=True):
            o["mean"] = np.mean(r["samples"], axis=0).tolist()
            o["sd"] = np.std(r["samples"], axis=0, ddof=1).tolist()
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
