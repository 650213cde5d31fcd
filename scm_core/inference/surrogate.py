"""Delayed acceptance (Christen & Fox 2005) with a surrogate of the model's responses.

Each Metropolis step first screens the proposal x' with a cheap approximation pi~ of the
tempered target: it goes on only with probability min(1, pi~(x') / pi~(x)); only then is the
model run, and the move is accepted with min(1, pi(x') pi~(x) / (pi(x) pi~(x'))). The two stages
together are reversible with respect to the exact pi, so the chain targets the exact tempered
posterior whatever the surrogate's error (a poor surrogate only costs acceptance).

The surrogate predicts the likelihood's *responses* (a study's steady F, T, z per dataset) from
the parameters that drive them, and pi~ is the exact likelihood of those predicted responses:
the prediction-error sigmas, offsets, bounds and the tempering act exactly. It is a local
thin-plate-spline radial basis function interpolant (scipy's ``RBFInterpolator`` with
``neighbors``: each prediction solves its own small system from its nearest training points;
rows are predicted one at a time, so a row's value does not depend on the other rows of a
batch) fitted on the distinct starting
states of the stage's chains and their stored responses: a function of the stage plan alone, so
a resumed or redelivered batch, or any number of workers, sees the same first stage.

A likelihood opts in by implementing :class:`ResponseLikelihood`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import RBFInterpolator

__all__ = ["ResponseLikelihood", "ResponseSurrogate", "fit_surrogate", "supports_surrogate"]

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


@dataclass(frozen=True, eq=False)
class ResponseSurrogate:
    """A fitted surrogate: ``predict(X)`` (m, k) responses at parameter vectors X (m, d)."""

    inputs: tuple[int, ...]
    center: NDArray[np.float64]
    scale: NDArray[np.float64]
    y_center: NDArray[np.float64]
    y_scale: NDArray[np.float64]
    interpolant: RBFInterpolator
    n_points: int

    def predict(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """Responses (m, k) at X (m, d), row by row: scipy evaluates a batch with matrix
        products whose rounding depends on the batch, and a row's value must not."""
        U = (np.asarray(X, dtype=float)[:, list(self.inputs)] - self.center) / self.scale
        out = np.empty((U.shape[0], self.y_center.shape[0]))
        for i in range(U.shape[0]):
            out[i] = self.interpolant(U[i : i + 1])[0]
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
    try:
        interp = RBFInterpolator(
            (U - center) / scale,
            (R - y_center) / y_scale,
            neighbors=k,
            kernel="thin_plate_spline",
            degree=1,
            smoothing=smoothing,
        )
    except (ValueError, np.linalg.LinAlgError):
        return None
    return ResponseSurrogate(
        inputs, center, scale, y_center, y_scale, interp, n_points=int(X.shape[0])
    )
