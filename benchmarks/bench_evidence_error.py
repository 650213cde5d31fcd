"""Are TMCMC's log-evidence standard errors right? Replicate runs on exact evidences and on the
quick case.

Exact evidences (``--replicates`` runs, seeds 0..R-1, ``--samples`` each):

* ``linear-gaussian``: the 5-D problem of the exact-answer tests (theta ~ N(0, I), eight
  observations y = A theta + N(0, 0.1^2), A and y drawn with seed 1): log Z is the log density
  of y under N(0, s^2 I + A A^T);
* ``bimodal``: theta ~ N(0, I) in 2-D and L = 0.3 N(mu, 0.2^2 I) + 0.7 N(-mu, 0.2^2 I), mu =
  (1.5, 1.5): Z = sum_k w_k N(mu_k; 0, 1.04 I). The modes lie 21 component sds apart, so no chain
  crosses and the mode masses rest on the stage-0 draws.

Per form and problem the table gives the mean error of log Z, its empirical sd over the
replicates, the root mean square of the reported standard errors, their ratio (1 if the errors
are right; its own relative error is about 1 / sqrt(2 (R - 1))), and the coverage: the share of
runs whose reported +-1 se holds the exact log Z (about 68 % if the errors are right; its sd is
sqrt(0.68 * 0.32 / R)), for the reported error (the genealogy estimate, never below the
stage-wise sum) and for the stage-wise sum alone (each stage's mean weight as an iid
average).

``--quick SEED ...`` also runs ``scm-calib calibrate examples/quick.toml --seed SEED --out
QUICK_DIR/seed_SEED`` (``--quick-dir``; a finished folder is read, not run again; each run
about 1-2 minutes on two idle cores) and gives the same coverage with the replicates' mean
log Z as the reference; ``--quick-form cmu`` runs it with the CMU cases' sampler instead
(resample-move, two surrogate transitions a stage: slowly mixing chains; 300 samples). Each
folder's errors are rescored: its stages are planned again with today's code (the samples and
log Z do not change, only the error), so folders written by earlier code count as new ones.

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_evidence_error.py [--replicates 100] [--samples 500]
        [--problems linear-gaussian bimodal] [--forms slow resample-move waste-free-da ...]
        [--quick 1 2 3 4 5 6 7 8 --quick-dir quick_runs] [--quick-form case|cmu]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy import stats

from scm_core.calibration.case import load_case
from scm_core.inference import JointPrior, StageState, TMCMCSettings, TruncatedNormal, run_tmcmc
from scm_core.inference.tmcmc.stage import plan_stage

WASTE_FREE_DA = {"moves": "waste-free", "n_steps": 4, "delayed_acceptance": True}
FORMS = {
    "slow": TMCMCSettings(n_steps=2),
    "slow-multinomial": TMCMCSettings(n_steps=2, resampling="multinomial"),
    "resample-move": TMCMCSettings(),
    "resample-move-multinomial": TMCMCSettings(resampling="multinomial"),
    "leader": TMCMCSettings(moves="leader"),
    "waste-free-da": TMCMCSettings(**WASTE_FREE_DA, surrogate_steps=10),
    "waste-free-da-multinomial": TMCMCSettings(
        **WASTE_FREE_DA, surrogate_steps=10, resampling="multinomial"
    ),
}
DEFAULT_FORMS = ["slow", "resample-move", "waste-free-da-multinomial", "waste-free-da"]
QUICK_CASE = Path(__file__).resolve().parents[1] / "examples" / "quick.toml"
#: the CMU cases' sampler (examples/cmu_*.toml: resample-move, two surrogate transitions of 50
#: steps a stage, systematic resampling) on the quick case, at 300 samples
CMU_SAMPLER = """n_samples = 300
moves = "resample-move"
delayed_acceptance = true
surrogate_steps = 50
n_steps = 2
"""

Problem = tuple[JointPrior, Callable[[np.ndarray], object], float]


def linear_gaussian() -> Problem:
    """(prior, likelihood returning (log L, responses), exact log Z)."""
    rng = np.random.default_rng(1)
    A, s = rng.normal(size=(8, 5)), 0.1
    y = A @ rng.normal(size=5) + s * rng.normal(size=8)
    prior = JointPrior({f"t{j}": TruncatedNormal(0.0, 1.0, -10.0, 10.0) for j in range(5)})
    log_norm = -0.5 * len(y) * math.log(2.0 * math.pi * s * s)

    def log_likelihood(X: np.ndarray):
        pred = X @ A.T
        return log_norm - 0.5 * np.sum((pred - y) ** 2, axis=1) / s**2, pred

    cov_y = s * s * np.eye(len(y)) + A @ A.T
    return (
        prior,
        log_likelihood,
        float(stats.multivariate_normal(np.zeros(len(y)), cov_y).logpdf(y)),
    )


def bimodal() -> Problem:
    """(prior, mixture likelihood, exact log Z): two modes no chain crosses."""
    mu, w, sd = np.array([[1.5, 1.5], [-1.5, -1.5]]), np.array([0.3, 0.7]), 0.2
    prior = JointPrior({f"t{j}": TruncatedNormal(0.0, 1.0, -10.0, 10.0) for j in range(2)})
    comps = [stats.multivariate_normal(m, sd * sd * np.eye(2)) for m in mu]

    def log_likelihood(X: np.ndarray) -> np.ndarray:
        parts = [math.log(wk) + c.logpdf(X) for wk, c in zip(w, comps, strict=True)]
        return np.logaddexp(*parts).reshape(-1)

    marginal = stats.multivariate_normal(np.zeros(2), (1.0 + sd * sd) * np.eye(2))
    log_z = np.logaddexp(*[math.log(wk) + marginal.logpdf(m) for wk, m in zip(w, mu, strict=True)])
    return prior, log_likelihood, float(log_z)


PROBLEMS = {"linear-gaussian": linear_gaussian, "bimodal": bimodal}


def coverage_row(
    label: Sequence[str],
    err: np.ndarray,
    se: np.ndarray,
    stagewise: np.ndarray,
    seconds: float,
) -> list[str]:
    """Table cells: replicates, mean error, sd, rms se, sd / se, coverage (reported and
    stage-wise), wall time."""
    sd, rms = float(err.std(ddof=1)), float(np.sqrt(np.mean(se**2)))
    return [
        *label,
        str(err.size),
        f"{err.mean():+.3f}",
        f"{sd:.3f}",
        f"{rms:.3f}",
        f"{sd / rms:.2f}",
        f"{np.mean(np.abs(err) <= se):.2f}",
        f"{np.mean(np.abs(err) <= stagewise):.2f}",
        f"{seconds:.0f}",
    ]


def rescored(
    stages: Sequence[StageState], prior: JointPrior, settings: TMCMCSettings
) -> tuple[float, float]:
    """(log Z var, stage-wise var) of stored stages as today's code reports them: every stage
    planned again from its predecessor with the variances carried forward (a folder written
    by earlier code; the samples are the same either way)."""
    state = dataclasses.replace(stages[0], log_evidence_var=0.0, log_evidence_var_stagewise=0.0)
    for nxt in stages[1:]:
        plan = plan_stage(state, prior, settings)
        state = dataclasses.replace(
            nxt,
            log_evidence_var=plan.log_evidence_var,
            log_evidence_var_stagewise=plan.log_evidence_var_stagewise,
        )
    return state.log_evidence_var, state.log_evidence_var_stagewise


def cmu_form_case(where: Path) -> Path:
    """examples/quick.toml with :data:`CMU_SAMPLER` as its [sampler], written to ``where``."""
    text = QUICK_CASE.read_text(encoding="utf-8")
    head, rest = text.split("[sampler]\n", 1)
    rest = "[data]\n" + rest.split("[data]\n", 1)[1]
    for name in ("wf34_s020.csv", "wf34_s050.csv"):
        rest = rest.replace(f'"{name}"', json.dumps(str(QUICK_CASE.parent / name)))
    where.parent.mkdir(parents=True, exist_ok=True)
    where.write_text(f"{head}[sampler]\n{CMU_SAMPLER}\n{rest}", encoding="utf-8")
    return where


def quick_run(seed: int, out: Path, case_file: Path = QUICK_CASE) -> tuple[float, float, float]:
    """(log Z, reported se, stage-wise se) of the case with ``seed``, run if not done."""
    from services.stages.folder import FolderStages

    if not (out / "summary.json").is_file():
        cmd = [sys.executable, "-m", "services.cli", "calibrate", str(case_file)]
        cmd += ["--seed", str(seed), "--out", str(out), "--no-plots", "--quiet"]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    case = load_case(case_file)
    store = FolderStages(out)
    stages = [store.state(i) for i in range(store.count())]
    var, stagewise = rescored(stages, case.prior(), case.tmcmc_settings())
    return stages[-1].log_evidence, math.sqrt(var), math.sqrt(stagewise)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--replicates", type=int, default=100)
    ap.add_argument("--samples", type=int, default=500)
    ap.add_argument("--problems", nargs="*", choices=list(PROBLEMS), default=list(PROBLEMS))
    ap.add_argument("--forms", nargs="*", choices=list(FORMS), default=DEFAULT_FORMS)
    ap.add_argument("--quick", nargs="*", type=int, default=[], metavar="SEED")
    ap.add_argument("--quick-dir", type=Path, default=Path("quick_runs"))
    ap.add_argument(
        "--quick-form",
        choices=("case", "cmu"),
        default="case",
        help="the quick case's own sampler, or the CMU cases' (CMU_SAMPLER)",
    )
    args = ap.parse_args()
    table = Table(title=f"log Z +- 1 se: coverage of the exact value, {args.samples} samples")
    for col in (
        "problem",
        "form",
        "replicates",
        "mean error",
        "empirical sd",
        "rms reported se",
        "sd / se",
        "coverage",
        "coverage stage-wise",
        "wall s",
    ):
        table.add_column(col, justify="left" if col in ("problem", "form") else "right")
    for name in args.problems:
        prior, f, log_z = PROBLEMS[name]()
        for form in args.forms:
            t0 = time.perf_counter()
            out = []  # (error, se, stage-wise se) per run; the runs themselves not kept
            for r in range(args.replicates):
                res = run_tmcmc(f, prior, args.samples, seed=r, settings=FORMS[form])
                se_pair = (res.log_evidence_se, res.log_evidence_se_stagewise)
                out.append((res.log_evidence - log_z, *se_pair))
            err, se, stagewise = np.array(out).T
            elapsed = time.perf_counter() - t0
            table.add_row(*coverage_row((name, form), err, se, stagewise, elapsed))
    if args.quick:
        t0 = time.perf_counter()
        case_file = QUICK_CASE
        if args.quick_form == "cmu":
            case_file = cmu_form_case(args.quick_dir / "quick_cmu.toml")
        runs = [quick_run(s, args.quick_dir / f"seed_{s}", case_file) for s in args.quick]
        rows = np.array(runs)
        err = rows[:, 0] - rows[:, 0].mean()
        form = "its own" if args.quick_form == "case" else "the CMU cases'"
        label = ("examples/quick.toml", f"{form}, vs mean")
        table.add_row(*coverage_row(label, err, rows[:, 1], rows[:, 2], time.perf_counter() - t0))
        for s, (z, se, sw) in zip(args.quick, rows, strict=True):
            print(f"quick seed {s}: log Z {z:.3f} +- {se:.3f} (stage-wise {sw:.3f})")
    Console(width=160).print(table)


if __name__ == "__main__":
    main()
