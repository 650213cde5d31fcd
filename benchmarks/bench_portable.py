"""What the CPU-independent numerics cost (issue 71): scm_core.inference.portable against the
numpy/LAPACK calls they replace, at the sizes the sampler uses, medians of several runs.

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_portable.py [--repeats 7]

Rows: the elementwise exp and log of a stage's n = 2000 values, the log-sum-exp of its weights,
the weighted covariance and Cholesky factor of 2000 samples in 8 dimensions (once per stage),
and the surrogate's local systems (4000 rows of 59 unknowns, 6 right-hand sides: the 50
nearest neighbours, the constant and 8 linear terms; two datasets of 3 responses), solved one
system at a time (LAPACK's batched gesv against numba's elimination with partial pivoting).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.special import logsumexp

from scm_core.inference import portable


def _median_s(fn: Callable[[], object], repeats: int) -> float:
    fn()  # compile / warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    x = rng.normal(size=2000) * 10
    X = rng.normal(size=(2000, 8))
    w = rng.random(2000)
    w /= w.sum()
    A = rng.normal(size=(4000, 59, 59)) + 10.0 * np.eye(59)
    B = rng.normal(size=(4000, 59, 6))

    def numpy_cov() -> object:
        m = w @ X
        c = ((X - m) * w[:, None]).T @ (X - m)
        return np.linalg.cholesky(0.5 * (c + c.T))

    rows = [
        ("exp, 2000 values", lambda: np.exp(x), lambda: portable.exp(x)),
        ("log, 2000 values", lambda: np.log(np.abs(x)), lambda: portable.log(np.abs(x))),
        ("logsumexp, 2000 values", lambda: logsumexp(x), lambda: portable.logsumexp(x)),
        ("covariance + Cholesky, 2000 x 8", numpy_cov,
         lambda: portable.cholesky(portable.weighted_covariance(X, w))),
        ("4000 systems 59 x 59, 6 rhs", lambda: np.linalg.solve(A, B),
         lambda: portable.solve_systems(A, B)),
    ]  # fmt: skip
    table = Table(title=f"numpy/LAPACK vs portable, median of {args.repeats} [ms]")
    for col in ("operation", "numpy", "portable", "ratio"):
        table.add_column(col, justify="left" if col == "operation" else "right")
    for name, before, after in rows:
        a, b = _median_s(before, args.repeats), _median_s(after, args.repeats)
        table.add_row(name, f"{1e3 * a:.3f}", f"{1e3 * b:.3f}", f"{b / a:.2f}")
    Console(width=120).print(table)


if __name__ == "__main__":
    main()
