"""Numerics whose bits do not depend on the CPU (issue 71): what the sampler computes with them
gives the same stages, samples and evidence on every x86-64 CPU.

Two things in numpy give different bits on different CPUs for the same inputs, measured on an
AVX-512 machine by switching them off: OpenBLAS picks its kernels for the CPU it finds
(``OPENBLAS_CORETYPE`` Haswell, SkylakeX, Zen, Sandybridge change matrix products, Cholesky
factors and solves in the last bits), and numpy's float64 ``exp``, ``log``, ``log1p``,
``expm1`` and ``power`` have AVX-512 versions that differ from its others
(``NPY_DISABLE_CPU_FEATURES``). Here the same operations are plain loops compiled by numba,
in a fixed order of operations (no reassociation: numba leaves fast-math off), and the
transcendental functions are the C library's (``math.exp`` ...), one element at a time.

Not covered, and said in docs/layers.md: glibc's ``exp``/``log``/``pow`` choose an FMA version
on CPUs that have FMA (every x86-64 CPU since 2013-2015: Intel Haswell, AMD Piledriver and
Zen), which differs in rare last bits from the version older CPUs run; another C library
(musl, macOS, Windows) computes them its own way.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "cholesky",
    "exp",
    "log",
    "log1p",
    "logsumexp",
    "lower_inverse",
    "solve_systems",
    "weighted_covariance",
    "weighted_mean",
]


@njit(cache=True)
def _exp(x: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = math.exp(x[i])
    return out


@njit(cache=True)
def _log(x: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.empty_like(x)
    for i in range(x.size):
        v = x[i]
        out[i] = math.log(v) if v > 0.0 else (-np.inf if v == 0.0 else np.nan)
    return out


@njit(cache=True)
def _log1p(x: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.empty_like(x)
    for i in range(x.size):
        v = x[i]
        out[i] = math.log1p(v) if v > -1.0 else (-np.inf if v == -1.0 else np.nan)
    return out


def _elementwise(kernel, x: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(x, dtype=np.float64)
    flat = np.ascontiguousarray(a).reshape(-1)
    return kernel(flat).reshape(a.shape)


def exp(x: ArrayLike) -> NDArray[np.float64]:
    """e**x elementwise (the C library's exp; numpy's differs on AVX-512 CPUs)."""
    return _elementwise(_exp, x)


def log(x: ArrayLike) -> NDArray[np.float64]:
    """Natural logarithm elementwise: -inf at 0, NaN below (as numpy, without its warning)."""
    return _elementwise(_log, x)


def log1p(x: ArrayLike) -> NDArray[np.float64]:
    """log(1 + x) elementwise: -inf at -1, NaN below."""
    return _elementwise(_log1p, x)


@njit(cache=True)
def _logsumexp(a: NDArray[np.float64]) -> float:
    top = -np.inf
    for v in a:
        if v > top:
            top = v
    if not np.isfinite(top):
        return top
    total = 0.0
    for v in a:
        total += math.exp(v - top)
    return top + math.log(total)


def logsumexp(a: ArrayLike) -> float:
    """log(sum(exp(a))) of a 1-D array, shifted by its largest value, summed in order; -inf
    for an empty or all -inf array, +inf if any value is +inf."""
    flat = np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(-1))
    return float(_logsumexp(flat)) if flat.size else -math.inf


@njit(cache=True)
def weighted_mean(X: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum_i w_i x_i over the rows of X (n, d), in row order."""
    n, d = X.shape
    out = np.zeros(d)
    for i in range(n):
        for j in range(d):
            out[j] += w[i] * X[i, j]
    return out


@njit(cache=True)
def weighted_covariance(X: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum_i w_i (x_i - m)(x_i - m)^T with m = Sum_i w_i x_i (w summing to 1), symmetric by
    construction (each pair summed once)."""
    n, d = X.shape
    m = weighted_mean(X, w)
    out = np.zeros((d, d))
    for i in range(n):
        for a in range(d):
            da = (X[i, a] - m[a]) * w[i]
            for b in range(a + 1):
                out[a, b] += da * (X[i, b] - m[b])
    for a in range(d):
        for b in range(a):
            out[b, a] = out[a, b]
    return out


@njit(cache=True)
def _cholesky(A: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
    d = A.shape[0]
    L = np.zeros((d, d))
    for j in range(d):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return L, False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, d):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    return L, True


def cholesky(A: ArrayLike) -> NDArray[np.float64]:
    """The lower Cholesky factor L (L L^T = A) of a symmetric positive definite matrix (the
    Cholesky-Banachiewicz order); ``np.linalg.LinAlgError`` if A is not positive definite."""
    L, ok = _cholesky(np.ascontiguousarray(A, dtype=np.float64))
    if not ok:
        raise np.linalg.LinAlgError("matrix is not positive definite")
    return L


@njit(cache=True)
def lower_inverse(L: NDArray[np.float64]) -> NDArray[np.float64]:
    """The inverse of a lower triangular matrix with a nonzero diagonal (forward
    substitution, column by column); lower triangular itself."""
    d = L.shape[0]
    inv = np.zeros((d, d))
    for c in range(d):
        for i in range(c, d):
            s = 1.0 if i == c else 0.0
            for k in range(c, i):
                s -= L[i, k] * inv[k, c]
            inv[i, c] = s / L[i, i]
    return inv


@njit(cache=True)
def solve_systems(A: NDArray[np.float64], B: NDArray[np.float64]) -> NDArray[np.float64]:
    """X[i] = A[i]^-1 B[i] for each of the systems A (m, k, k), B (m, k, s): Gaussian
    elimination with partial pivoting on the augmented rows [A[i] | B[i]], one system at a
    time, then back substitution; a singular system's rows are NaN."""
    m, k, s = B.shape
    n = k + s
    out = np.full((m, k, s), np.nan)
    M = np.empty((k, n))  # the augmented system, rows contiguous (the updates vectorise)
    for i in range(m):
        M[:, :k] = A[i]
        M[:, k:] = B[i]
        singular = False
        for c in range(k):
            p = c
            big = abs(M[c, c])
            for r in range(c + 1, k):
                if abs(M[r, c]) > big:
                    big = abs(M[r, c])
                    p = r
            if big == 0.0:
                singular = True
                break
            if p != c:
                for j in range(n):
                    M[c, j], M[p, j] = M[p, j], M[c, j]
            pivot_row = M[c]
            for r in range(c + 1, k):
                row = M[r]
                f = row[c] / pivot_row[c]
                if f != 0.0:
                    for j in range(c + 1, n):
                        row[j] -= f * pivot_row[j]
        if singular:
            continue
        for c in range(k - 1, -1, -1):
            for j in range(s):
                t = M[c, k + j]
                for q in range(c + 1, k):
                    t -= M[c, q] * out[i, q, j]
                out[i, c, j] = t / M[c, c]
    return out
