"""Speed of the delayed-acceptance surrogate's predictions (issue 12): one table.

The surrogate (``scm_core/inference/surrogate.py``) is a local thin-plate-spline RBF
interpolant (50 nearest neighbours, linear term): each predicted row solves its own
(k + d + 1)-square system. A surrogate transition makes K such predictions per chain and move
(K = 40 in the accelerated form), so on paper case 1 at 2000 samples a study makes about
400,000 of them. Rows of a chain-like query (points near the training states) are predicted
by:

* scipy: ``scipy.interpolate.RBFInterpolator(neighbors=50, kernel="thin_plate_spline")``, the
  formulation the surrogate follows (its rows depend on their batch, so it is not used);
* numpy: the element-wise numpy formulation the surrogate used before (batched kernel matrices
  and LAPACK solves; kept here as the "before");
* numba: the surrogate's ``local_tps`` (a numba loop, one solve per row; the "after");

plus the k-d tree query that finds the neighbours (the same for all three). Medians of
``--repeats`` runs in microseconds per row, and each method's largest difference from scipy.

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_surrogate.py [--train 12000] [--rows 4000] [--dim 5]
        [--repeats 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from numpy.typing import NDArray
from rich.console import Console
from rich.table import Table
from scipy.interpolate import RBFInterpolator

from scm_core.inference.surrogate import fit_surrogate, local_tps

NEIGHBORS = 50
SMOOTHING = 1e-3


def _tps(r: NDArray[np.float64]) -> NDArray[np.float64]:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r > 0.0, r * r * np.log(np.where(r > 0.0, r, 1.0)), 0.0)


def local_tps_numpy(
    points: NDArray[np.float64],
    values: NDArray[np.float64],
    neighbors: NDArray[np.intp],
    U: NDArray[np.float64],
    smoothing: float,
) -> NDArray[np.float64]:
    """The element-wise numpy formulation the surrogate used before the numba kernel."""
    Y = points[neighbors]
    D = values[neighbors]
    m, k, d = Y.shape
    lo, hi = Y.min(axis=1), Y.max(axis=1)
    shift = (hi + lo) / 2.0
    scale = np.where((hi - lo) == 0.0, 1.0, (hi - lo) / 2.0)
    Yhat = (Y - shift[:, None, :]) / scale[:, None, :]
    r2 = np.zeros((m, k, k))
    for j in range(d):
        diff = Y[:, :, None, j] - Y[:, None, :, j]
        r2 += diff * diff
    A = np.zeros((m, k + d + 1, k + d + 1))
    A[:, :k, :k] = _tps(np.sqrt(r2)) + smoothing * np.eye(k)
    A[:, :k, k] = 1.0
    A[:, :k, k + 1 :] = Yhat
    A[:, k, :k] = 1.0
    A[:, k + 1 :, :k] = np.swapaxes(Yhat, 1, 2)
    B = np.zeros((m, k + d + 1, D.shape[2]))
    B[:, :k] = D
    coeffs = np.linalg.solve(A, B)
    rx = np.sqrt(((U[:, None, :] - Y) ** 2).sum(axis=-1))
    vec = np.concatenate([_tps(rx), np.ones((m, 1)), (U - shift) / scale], axis=1)
    return (vec[:, :, None] * coeffs).sum(axis=1)


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--train", type=int, default=12_000, help="training states")
    ap.add_argument("--rows", type=int, default=4000, help="rows predicted per call")
    ap.add_argument("--dim", type=int, default=5, help="parameters the responses depend on")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()

    rng = np.random.default_rng(0)
    X = rng.normal(size=(args.train, args.dim))
    R = np.column_stack(
        [np.sin(X[:, 0]) + X[:, 1] ** 2, X[:, 2] * X[:, 3 % args.dim], np.exp(X[:, 0] / 3)]
    )
    sur = fit_surrogate(X, R, tuple(range(args.dim)), NEIGHBORS, SMOOTHING)
    assert sur is not None
    # queries near training states, as a chain's proposals are
    Q = X[rng.integers(0, args.train, args.rows)] + 0.1 * rng.normal(size=(args.rows, args.dim))
    U = (Q - sur.center) / sur.scale
    _, idx = sur.tree.query(U, k=NEIGHBORS)
    idx = np.ascontiguousarray(idx, dtype=np.intp)
    local_tps(sur.points, sur.values, idx[:2], U[:2], SMOOTHING)  # compile or load the cache

    scipy_rbf = RBFInterpolator(
        sur.points, sur.values, neighbors=NEIGHBORS, kernel="thin_plate_spline", smoothing=SMOOTHING
    )
    ref = scipy_rbf(U)
    methods = {
        "scipy RBFInterpolator": (lambda: scipy_rbf(U), None),
        "numpy (before)": (
            lambda: local_tps_numpy(sur.points, sur.values, idx, U, SMOOTHING),
            True,
        ),
        "numba local_tps (after)": (
            lambda: local_tps(sur.points, sur.values, idx, U, SMOOTHING),
            True,
        ),
        "k-d tree query (all)": (lambda: sur.tree.query(U, k=NEIGHBORS), None),
    }
    table = Table(
        title=f"surrogate rows: {args.train} training states in {args.dim}-D, {args.rows} rows, "
        f"median of {args.repeats}"
    )
    for col in ("method", "us per row", "max |diff| from scipy"):
        table.add_column(col, justify="right")
    for name, (fn, compare) in methods.items():
        t = _median_time(fn, args.repeats)
        diff = float(np.abs(fn() - ref).max()) if compare else None
        table.add_row(name, f"{t / args.rows * 1e6:.1f}", "-" if diff is None else f"{diff:.1e}")
    Console(width=120).print(table)


if __name__ == "__main__":
    main()
