"""Are TMCMC's log-evidence standard errors right? Replicate runs on an exact evidence.

The target is the 5-D linear-Gaussian problem of the exact-answer tests (theta ~ N(0, I), eight
observations y = A theta + N(0, 0.1^2), A and y drawn with seed 1): its log evidence is the
log density of y under N(0, s^2 I + A A^T), exact. Each form runs ``--replicates`` times (seeds
0..R-1); the table gives the mean error of log Z, its empirical sd over the replicates, the root
mean square of the standard errors the runs report, their ratio (1 if the reported errors are
right; the ratio's own relative error is about 1 / sqrt(2 (R - 1))) and the replicates whose
error exceeds two reported standard errors (about 5 % of them if the errors are right). The
``-multinomial`` forms resample with independent draws and report Lee & Whiteley's genealogy
estimate; the others the sum of per-stage terms.

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_evidence_error.py [--replicates 12] [--samples 2000]
        [--forms resample-move waste-free-da resample-move-multinomial]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy import stats

from scm_core.inference import JointPrior, TMCMCSettings, TruncatedNormal, run_tmcmc

WASTE_FREE_DA = {"moves": "waste-free", "n_steps": 4, "delayed_acceptance": True}
FORMS = {
    "resample-move": TMCMCSettings(),
    "leader": TMCMCSettings(moves="leader"),
    "waste-free-da": TMCMCSettings(**WASTE_FREE_DA, surrogate_steps=10),
    "resample-move-multinomial": TMCMCSettings(resampling="multinomial"),
    "waste-free-da-multinomial": TMCMCSettings(
        **WASTE_FREE_DA, surrogate_steps=10, resampling="multinomial"
    ),
}


def problem() -> tuple[JointPrior, object, float]:
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--replicates", type=int, default=12)
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--forms", nargs="+", choices=list(FORMS), default=list(FORMS))
    args = ap.parse_args()
    prior, f, log_z = problem()
    table = Table(title=f"log Z on the 5-D linear-Gaussian target, {args.samples} samples")
    for col in (
        "form",
        "replicates",
        "mean error",
        "empirical sd",
        "rms reported se",
        "sd / se",
        "|error| > 2 se",
        "wall s",
    ):
        table.add_column(col, justify="left" if col == "form" else "right")
    for form in args.forms:
        t0 = time.perf_counter()
        runs = [
            run_tmcmc(f, prior, args.samples, seed=r, settings=FORMS[form])
            for r in range(args.replicates)
        ]
        err = np.array([r.log_evidence - log_z for r in runs])
        se = np.array([r.log_evidence_se for r in runs])
        sd, rms = float(err.std(ddof=1)), float(np.sqrt(np.mean(se**2)))
        table.add_row(
            form,
            str(args.replicates),
            f"{err.mean():+.3f}",
            f"{sd:.3f}",
            f"{rms:.3f}",
            f"{sd / rms:.2f}",
            str(int(np.sum(np.abs(err) > 2.0 * se))),
            f"{time.perf_counter() - t0:.0f}",
        )
    Console(width=140).print(table)


if __name__ == "__main__":
    main()
