"""Surrogate transitions (Liu 2001, section 9.4.3; with one inner step, Christen & Fox's 2005
delayed acceptance) with a surrogate of the model's responses.

A move makes K Metropolis steps on a cheap approximation pi~ of the tempered target, from x to
y, without running the model; if they moved, the model runs once at y and y is accepted with
min(1, pi(y) pi~(x) / (pi(x) pi~(y))). K steps of a pi~-reversible kernel are pi~-reversible,
so the move is reversible with respect to the exact pi and the chain targets the exact
tempered posterior whatever the surrogate's error (a poor surrogate only costs acceptance).
pi~ is floored where the surrogate gives no finite value (a constant of the stage plan), so it
is positive wherever the prior is. With a good surrogate most moves cost one model run however
far the K inner steps went, instead of one run per step.

The surrogate predicts the likelihood's *responses* (a study's steady F, T, z per dataset) from
the parameters that drive them, and pi~ is the exact likelihood of those predicted responses:
the prediction-error sigmas, offsets, bounds and the tempering act exactly. It is a local
thin-plate-spline radial basis function interpolant with a linear term, the formulation of
scipy's ``RBFInterpolator`` with ``neighbors`` (each prediction solves its own small system
from its nearest training points; :func:`local_tps`), fitted on the distinct starting
states of the stage's chains and their stored responses: a function of the stage plan alone, so
a resumed or redelivered batch, or any number of workers, sees the same first stage. The
system of each row is built and solved on its own (a numba loop, one LAPACK solve per row),
so a row's value does not depend on the other rows of the batch (scipy's own evaluation groups
rows into matrix products whose rounding does).

A likelihood opts in by implementing :class:`ResponseLikelihood`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.spatial import cKDTree

__all__ = [
    "ResponseLikelihood",
    "ResponseSurrogate",
    "fit_surrogate",
    "local_tps",
    "supports_surrogate",
]

#: rows whose local systems are built and solved together (memory: rows x k x k floats)
CHUNK = 256

#: smallest training set (distinct states with finite responses) a surrogate is fitted on
MIN_POINTS = 20


@runtime_checkable
class ResponseLikelihood(Protocol):
    """A likelihood whose output at X follows from X and its responses R (m, k) alone:
    ``from_responses(X, R)`` returns what ``f(X)`` returns when the model gives R.
    ``response_inputs``: the parameter columns the responses depend on (the others, e.g. the
    prediction-error sigmas, act only in the likelihood)."""

    response_inputs: tuple[int, ...]

    def from_responses(self, X: NDArray[np.float64], R: NDArray[np.float64]) -> Any: ...


def supports_surrogate(f: object) -> bool:
    return isinstance(f, ResponseLikelihood)


@njit(cache=True)
def _tps_kernel(r2: float) -> float:
    """Thin-plate-spline kernel r^2 log r from r^2 (0 at r = 0)."""
    return 0.5 * r2 * np.log(r2) if r2 > 0.0 else 0.0


@njit(cache=True)
def local_tps(
    points: NDArray[np.float64],
    values: NDArray[np.float64],
    neighbors: NDArray[np.intp],
    U: NDArray[np.float64],
    smoothing: float,
) -> NDArray[np.float64]:
    """Local thin-plate-spline interpolation with a linear term at the rows of U (m, d):
    row i interpolates ``values`` (n, s) over its ``neighbors[i]`` (k indices into ``points``
    (n, d)), in the formulation of scipy's ``RBFInterpolator(kernel="thin_plate_spline",
    degree=1, neighbors=k, smoothing=...)``: polynomial coordinates shifted and scaled to the
    neighbours' box, kernel matrix plus ``smoothing`` on its diagonal. Each row builds and
    solves its own (k + d + 1)-square system (numba, one LAPACK solve per row), so a row's
    value does not depend on the other rows. A row whose system is singular gives NaN."""
    m, k = neighbors.shape
    d = points.shape[1]
    s = values.shape[1]
    n = k + d + 1
    out = np.full((m, s), np.nan)
    Y = np.empty((k, d))
    A = np.empty((n, n))
    B = np.empty((n, s))
    shift = np.empty(d)
    scale = np.empty(d)
    for i in range(m):
        for a in range(k):
            for j in range(d):
                Y[a, j] = points[neighbors[i, a], j]
        for j in range(d):
            lo = Y[0, j]
            hi = Y[0, j]
            for a in range(1, k):
                lo = min(lo, Y[a, j])
                hi = max(hi, Y[a, j])
            shift[j] = (hi + lo) / 2.0
            half = (hi - lo) / 2.0
            scale[j] = half if half != 0.0 else 1.0
        A[:, :] = 0.0
        for a in range(k):
            for b in range(a + 1, k):
                r2 = 0.0
                for j in range(d):
                    diff = Y[a, j] - Y[b, j]
                    r2 += diff * diff
                v = _tps_kernel(r2)
                A[a, b] = v
                A[b, a] = v
            A[a, a] = smoothing
            A[a, k] = 1.0
            A[k, a] = 1.0
            for j in range(d):
                yhat = (Y[a, j] - shift[j]) / scale[j]
                A[a, k + 1 + j] = yhat
                A[k + 1 + j, a] = yhat
            for c in range(s):
                B[a, c] = values[neighbors[i, a], c]
        B[k:, :] = 0.0
        try:
            coef = np.linalg.solve(A, B)
        except Exception:  # a singular system (numba raises a plain exception)
            continue
        for c in range(s):
            acc = coef[k, c]
            for a in range(k):
                r2 = 0.0
                for j in range(d):
                    diff = U[i, j] - Y[a, j]
                    r2 += diff * diff
                acc += _tps_kernel(r2) * coef[a, c]
            for j in range(d):
                acc += (U[i, j] - shift[j]) / scale[j] * coef[k + 1 + j, c]
            out[i, c] = acc
    return out


@dataclass(frozen=True, eq=False)
class ResponseSurrogate:
    """A fitted surrogate: ``predict(X)`` (m, k) responses at parameter vectors X (m, d)."""

    inputs: tuple[int, ...]
    center: NDArray[np.float64]
    scale: NDArray[np.float64]
    y_center: NDArray[np.float64]
    y_scale: NDArray[np.float64]
    points: NDArray[np.float64]
    values: NDArray[np.float64]
    tree: cKDTree
    neighbors: int
    smoothing: float
    n_points: int

    def predict(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """Responses (m, k) at X (m, d); a row's value does not depend on the batch."""
        U = (np.asarray(X, dtype=float)[:, list(self.inputs)] - self.center) / self.scale
        out = np.empty((U.shape[0], self.y_center.shape[0]))
        for start in range(0, U.shape[0], CHUNK):
            rows = U[start : start + CHUNK]
            _, idx = self.tree.query(rows, k=self.neighbors)
            idx = np.asarray(idx, dtype=np.intp).reshape(rows.shape[0], self.neighbors)
            out[start : start + CHUNK] = local_tps(
                self.points, self.values, np.ascontiguousarray(idx), rows, self.smoothing
            )
        return out * self.y_scale + self.y_center


def fit_surrogate(
    samples: NDArray[np.float64],
    responses: NDArray[np.float64] | None,
    inputs: tuple[int, ...],
    neighbors: int,
    smoothing: float,
) -> ResponseSurrogate | None:
    """Fit on the distinct rows of ``samples`` (n, d) with finite ``responses`` (n, k); inputs
    and responses standardised by their mean and sd over the training set. None when there are
    fewer than :data:`MIN_POINTS` such rows or no responses."""
    if responses is None or responses.shape[1] == 0 or not inputs:
        return None
    X = np.asarray(samples, dtype=float)
    R = np.asarray(responses, dtype=float)
    finite = np.all(np.isfinite(R), axis=1) & np.all(np.isfinite(X), axis=1)
    X, R = X[finite], R[finite]
    if X.shape[0] == 0:
        return None
    _, first = np.unique(X, axis=0, return_index=True)
    first = np.sort(first)
    X, R = X[first], R[first]
    if X.shape[0] < MIN_POINTS:
        return None
    U = X[:, list(inputs)]
    center, scale = U.mean(axis=0), U.std(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    y_center, y_scale = R.mean(axis=0), R.std(axis=0)
    y_scale = np.where(y_scale > 0, y_scale, 1.0)
    k = int(min(neighbors, X.shape[0]))
    points = (U - center) / scale
    return ResponseSurrogate(
        inputs,
        center,
        scale,
        y_center,
        y_scale,
        points=points,
        values=(R - y_center) / y_scale,
        tree=cKDTree(points),
        neighbors=k,
        smoothing=float(smoothing),
        n_points=int(X.shape[0]),
    )
