"""How smooth is the likelihood where a population's particles sit? Paper case 1 on the example log.

A TMCMC population that holds one state many times over (a particle no move has left) is a sign
of a spike of the likelihood. This script takes a saved final population (``bench_study.py
--save DIR`` writes ``FORM_N.npy``), its ``--heavy`` most repeated states and ``--random``
distinct states drawn at random, and runs the simulator at each state and at ``--perturbations``
copies of it, each parameter multiplied by (1 + ``--relative`` * N(0, 1)). Per state it prints the
number of copies, k_c, the spread of the drawbar pull (sd of F / |mean F|) and of log L (nats)
over the runs that did not fail, and the failed runs. A smooth simulator gives spreads of the
order of the perturbation.

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_response_noise.py POPULATION.npy [--heavy 4]
        [--random 6] [--perturbations 8] [--relative 1e-6] [--seed 2]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_study import CASE, load_model
from rich.console import Console
from rich.table import Table

from scm_core.calibration import StudyModel, load_case


def spread(
    model: StudyModel, x: np.ndarray, k: int, rel: float, rng: np.random.Generator
) -> tuple[float, float, int]:
    """(sd F / |mean F|, sd log L, failed runs) over x and k perturbed copies of it."""
    X = np.vstack([x[None], x * (1.0 + rel * rng.standard_normal((k, x.size)))])
    ll, responses = model(X)
    ok = np.all(np.isfinite(responses), axis=1) & np.isfinite(ll)
    if ok.sum() < 2:
        return float("nan"), float("nan"), int((~ok).sum())
    F = responses[ok, 0]
    return float(F.std() / abs(F.mean())), float(ll[ok].std()), int((~ok).sum())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("population", type=Path, help="saved samples (n, d), case 1's parameters")
    ap.add_argument("--heavy", type=int, default=4)
    ap.add_argument("--random", type=int, default=6)
    ap.add_argument("--perturbations", type=int, default=8)
    ap.add_argument("--relative", type=float, default=1e-6)
    ap.add_argument("--seed", type=int, default=2)
    args = ap.parse_args()

    case = load_case(CASE)
    model = load_model(case)
    samples = np.load(args.population)
    states, copies = np.unique(samples, axis=0, return_counts=True)
    rng = np.random.default_rng(args.seed)
    heavy = np.argsort(-copies, kind="stable")[: args.heavy]
    drawn = rng.choice(states.shape[0], size=min(args.random, states.shape[0]), replace=False)
    names = list(case.prior().names)
    kc = names.index("k_c")

    table = Table(
        title=f"{args.population}: {states.shape[0]} distinct of {samples.shape[0]}; "
        f"{args.perturbations} perturbations of relative size {args.relative:g}"
    )
    for col in ("state", "copies", "k_c", "sd F / |F|", "sd log L", "failed runs"):
        table.add_column(col, justify="right")
    for label, rows in (("heaviest", heavy), ("random", drawn)):
        for i in rows:
            f_spread, ll_spread, failed = spread(
                model, states[i], args.perturbations, args.relative, rng
            )
            table.add_row(
                label,
                str(int(copies[i])),
                f"{states[i, kc]:+.2e}",
                f"{f_spread:.4f}",
                f"{ll_spread:.2f}",
                f"{failed} of {args.perturbations + 1}",
            )
    Console(width=140).print(table)


if __name__ == "__main__":
    main()
