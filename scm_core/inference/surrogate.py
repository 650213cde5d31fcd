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
system of each row is built and solved (numba loops, one system at a time) on its own,
so a row's value does not depend on the other rows of the batch (scipy's own evaluation groups
rows into matrix products whose rounding does).

A likelihood opts in by implementing :class:`ResponseLikelihood`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numba import njit
from numpy.typing import NDArray

from scm_core.inference.portable import solve_systems

if TYPE_CHECKING:
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
    prediction-error sigmas, act only in the likelihood). Optionally ``response_outputs``:
    the columns of R the output reads (a study's: the responses its datasets measured and its
    case fits); the surrogate predicts only those (NaN for the others), so a response no
    likelihood term reads is neither fitted nor needed in the training states (the lateral
    force of a study stored before it was simulated: NaN)."""

    response_inputs: tuple[int, ...]

    def from_responses(self, X: NDArray[np.float64], R: NDArray[np.float64]) -> Any: ...


def supports_surrogate(f: object) -> bool:
    return isinstance(f, ResponseLikelihood)


@njit(cache=True)
def _tps_kernel(r2: float) -> float:
    """Thin-plate-spline kernel r^2 log r from r^2 (0 at r = 0)."""
    return 0.5 * r2 * np.log(r2) if r2 > 0.0 else 0.0


@njit(cache=True)
def _local_systems(points, values, neighbors, smoothing):
    """The (k + d + 1)-square systems A c = B of the rows, and their neighbours' box (shift,
    scale) for the polynomial coordinates."""
    m, k = neighbors.shape
    d = points.shape[1]
    s = values.shape[1]
    n = k + d + 1
    A = np.zeros((m, n, n))
    B = np.zeros((m, n, s))
    shift = np.empty((m, d))
    scale = np.empty((m, d))
    for i in range(m):
        for j in range(d):
            lo = points[neighbors[i, 0], j]
            hi = lo
            for a in range(1, k):
                lo = min(lo, points[neighbors[i, a], j])
                hi = max(hi, points[neighbors[i, a], j])
            shift[i, j] = (hi + lo) / 2.0
            half = (hi - lo) / 2.0
            scale[i, j] = half if half != 0.0 else 1.0
        for a in range(k):
            pa = neighbors[i, a]
            for b in range(a + 1, k):
                pb = neighbors[i, b]
                r2 = 0.0
                for j in range(d):
                    diff = points[pa, j] - points[pb, j]
                    r2 += diff * diff
                v = _tps_kernel(r2)
                A[i, a, b] = v
                A[i, b, a] = v
            A[i, a, a] = smoothing
            A[i, a, k] = 1.0
            A[i, k, a] = 1.0
            for j in range(d):
                yhat = (points[pa, j] - shift[i, j]) / scale[i, j]
                A[i, a, k + 1 + j] = yhat
                A[i, k + 1 + j, a] = yhat
            for c in range(s):
                B[i, a, c] = values[pa, c]
    return A, B, shift, scale


@njit(cache=True)
def _local_values(points, neighbors, U, coef, shift, scale):
    """The interpolants with coefficients ``coef`` (m, k + d + 1, s) at the rows of U."""
    m, k = neighbors.shape
    d = points.shape[1]
    s = coef.shape[2]
    out = np.empty((m, s))
    for i in range(m):
        for c in range(s):
            acc = coef[i, k, c]
            for a in range(k):
                r2 = 0.0
                for j in range(d):
                    diff = U[i, j] - points[neighbors[i, a], j]
                    r2 += diff * diff
                acc += _tps_kernel(r2) * coef[i, a, c]
            for j in range(d):
                acc += (U[i, j] - shift[i, j]) / scale[i, j] * coef[i, k + 1 + j, c]
            out[i, c] = acc
    return out


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
    neighbours' box, kernel matrix plus ``smoothing`` on its diagonal. Each row's system is
    built and solved (numba loops: the same bits on every CPU, :mod:`.portable`) on its own, so
    a row's value does not depend on the other rows. A row whose system is singular gives NaN."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    values = np.ascontiguousarray(values, dtype=np.float64)
    neighbors = np.ascontiguousarray(neighbors, dtype=np.intp)
    U = np.ascontiguousarray(U, dtype=np.float64)
    A, B, shift, scale = _local_systems(points, values, neighbors, float(smoothing))
    coef = solve_systems(A, B)  # a singular system's rows are NaN
    return _local_values(points, neighbors, U, coef, shift, scale)


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
    outputs: tuple[int, ...] = ()  # the response columns fitted
    width: int = 0  # k: the responses' columns in all

    def predict(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """Responses (m, k) at X (m, d), NaN in the columns not fitted; a row's value does not
        depend on the batch."""
        U = (np.asarray(X, dtype=float)[:, list(self.inputs)] - self.center) / self.scale
        out = np.empty((U.shape[0], self.y_center.shape[0]))
        for start in range(0, U.shape[0], CHUNK):
            rows = U[start : start + CHUNK]
            _, idx = self.tree.query(rows, k=self.neighbors)
            idx = np.asarray(idx, dtype=np.intp).reshape(rows.shape[0], self.neighbors)
            out[start : start + CHUNK] = local_tps(
                self.points, self.values, idx, rows, self.smoothing
            )
        fitted = out * self.y_scale + self.y_center
        if len(self.outputs) == self.width:
            return fitted
        full = np.full((U.shape[0], self.width), np.nan)
        full[:, list(self.outputs)] = fitted
        return full


def fit_surrogate(
    samples: NDArray[np.float64],
    responses: NDArray[np.float64] | None,
    inputs: tuple[int, ...],
    neighbors: int,
    smoothing: float,
    outputs: tuple[int, ...] | None = None,
) -> ResponseSurrogate | None:
    """Fit the columns ``outputs`` of ``responses`` (n, k) (None: all) on the distinct rows of
    ``samples`` (n, d) where they are finite; inputs and responses standardised by their mean
    and sd over the training set. None when there are fewer than :data:`MIN_POINTS` such rows
    or no responses."""
    if responses is None or responses.shape[1] == 0 or not inputs:
        return None
    width = int(responses.shape[1])
    outputs = tuple(range(width)) if outputs is None else tuple(int(c) for c in outputs)
    if not outputs:
        return None
    X = np.asarray(samples, dtype=float)
    R = np.asarray(responses, dtype=float)
    if len(outputs) < width:
        R = R[:, list(outputs)]
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
    from scipy.spatial import cKDTree  # on first use (scipy.spatial: a second to import)

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
        outputs=outputs,
        width=width,
    )
