"""Test targets with exact answers whose likelihood is a sum of parts (early rejection) and
whose output follows from responses (a surrogate for delayed acceptance)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats

from scm_core.inference import JointPrior, TruncatedNormal

LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


class PartedLinearGaussian:
    """y = A theta + N(0, s^2), the rows of A grouped into parts; ``base`` parts go to the base
    density b of an update (output (log L(tempered parts), responses, log b)). The responses of
    a part are its predictions A_g theta. Full evaluation = assemble(all parts)."""

    def __init__(
        self,
        A: np.ndarray,
        y: np.ndarray,
        s: float,
        groups: Sequence[Sequence[int]],
        base: Sequence[bool] | None = None,
        order: Sequence[int] | None = None,
    ) -> None:
        self.A, self.y, self.s = A, y, s
        self.groups = [tuple(g) for g in groups]
        self.part_in_base = tuple(base) if base is not None else (False,) * len(self.groups)
        self.part_order = tuple(order) if order is not None else tuple(range(len(self.groups)))
        self.calls: list[tuple[int, int]] = []  # (part, rows) of every run_part
        self.response_inputs = tuple(range(A.shape[1]))

    def _pred(self, X: np.ndarray, k: int) -> np.ndarray:
        out = np.zeros((X.shape[0], len(self.groups[k])))
        for c, i in enumerate(self.groups[k]):
            for j in range(self.A.shape[1]):
                out[:, c] = out[:, c] + self.A[i, j] * X[:, j]
        return out

    def _term(self, k: int, pred: np.ndarray) -> np.ndarray:
        total = np.zeros(pred.shape[0])
        for c, i in enumerate(self.groups[k]):
            r = (self.y[i] - pred[:, c]) / self.s
            total = total - 0.5 * r * r
        return total - len(self.groups[k]) * (math.log(self.s) + LOG_SQRT_2PI)

    def run_part(self, X: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        self.calls.append((k, X.shape[0]))
        pred = self._pred(X, k)
        return self._term(k, pred), pred

    def part_bound(self, X: np.ndarray, k: int) -> np.ndarray:
        return np.full(X.shape[0], -len(self.groups[k]) * (math.log(self.s) + LOG_SQRT_2PI))

    def assemble(self, X: np.ndarray, responses: Sequence[np.ndarray]):
        ll = np.zeros(X.shape[0])
        base = np.zeros(X.shape[0])
        for k, pred in enumerate(responses):
            if self.part_in_base[k]:
                base = base + self._term(k, pred)
            else:
                ll = ll + self._term(k, pred)
        resp = np.concatenate(list(responses), axis=1)
        return (ll, resp, base) if any(self.part_in_base) else (ll, resp)

    def from_responses(self, X: np.ndarray, R: np.ndarray):
        widths = np.cumsum([0] + [len(g) for g in self.groups])
        return self.assemble(X, [R[:, widths[k] : widths[k + 1]] for k in range(len(self.groups))])

    def __call__(self, X: np.ndarray):
        return self.assemble(X, [self._pred(X, k) for k in range(len(self.groups))])


def exact_linear(A: np.ndarray, y: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Posterior mean, sd and log evidence of y = A theta + N(0, s^2), theta ~ N(0, I)."""
    cov = np.linalg.inv(np.eye(A.shape[1]) + A.T @ A / s**2)
    mean = cov @ A.T @ y / s**2
    cov_y = s**2 * np.eye(len(y)) + A @ A.T
    log_z = stats.multivariate_normal(np.zeros(len(y)), cov_y).logpdf(y)
    return mean, np.sqrt(np.diag(cov)), float(log_z)


class PartedBimodal:
    """Two parts, each a 2-D Gaussian mixture 0.1 N(-2, 0.5^2 I) + 0.9 N(2, 0.5^2 I) over its
    own pair of coordinates; the bound of a part is its density's maximum (the 0.9 mode's peak,
    plus the other mode's tail there, bounded by adding the two peaks)."""

    part_order = (0, 1)
    part_in_base = (False, False)
    response_inputs = (0, 1, 2, 3)

    def _term(self, X: np.ndarray, k: int) -> np.ndarray:
        Y = X[:, 2 * k : 2 * k + 2]
        q1 = ((Y + 2.0) / 0.5) ** 2
        q2 = ((Y - 2.0) / 0.5) ** 2
        c = -2.0 * (math.log(0.5) + LOG_SQRT_2PI)
        return (
            np.logaddexp(
                math.log(0.1) - 0.5 * (q1[:, 0] + q1[:, 1]),
                math.log(0.9) - 0.5 * (q2[:, 0] + q2[:, 1]),
            )
            + c
        )

    def run_part(self, X: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        t = self._term(X, k)
        return t, t[:, None]

    def part_bound(self, X: np.ndarray, k: int) -> np.ndarray:
        return np.full(X.shape[0], -2.0 * (math.log(0.5) + LOG_SQRT_2PI))  # log(0.1 + 0.9)

    def assemble(self, X: np.ndarray, responses: Sequence[np.ndarray]):
        return responses[0][:, 0] + responses[1][:, 0], np.concatenate(list(responses), axis=1)

    def from_responses(self, X: np.ndarray, R: np.ndarray):
        return self.assemble(X, [R[:, 0:1], R[:, 1:2]])

    def __call__(self, X: np.ndarray):
        return self.assemble(X, [self.run_part(X, k)[1] for k in range(2)])


# --- shared problems -----------------------------------------------------------------------

_rng = np.random.default_rng(1)
#: the 5-D linear-Gaussian problem of test_inference_tmcmc_accuracy (8 observations)
A5 = _rng.normal(size=(8, 5))
S5 = 0.1
Y5 = A5 @ _rng.normal(size=5) + S5 * _rng.normal(size=8)
#: N(0, I) truncated at +-10 sd per axis (truncated mass ~1e-22, negligible)
PRIOR5 = JointPrior({f"t{j}": TruncatedNormal(0.0, 1.0, -10.0, 10.0) for j in range(5)})


def parted_5d(order: Sequence[int] | None = None) -> PartedLinearGaussian:
    """The 5-D problem with its observations in four parts of two."""
    return PartedLinearGaussian(A5, Y5, S5, [(0, 1), (2, 3), (4, 5), (6, 7)], order=order)


def update_problem():
    """As test_inference_update: y1 then y2 (4 observations each, 2-D, sd 0.3). Returns (prior,
    the likelihood of y1 in two parts, the update's likelihood (y1's parts in the base density,
    y2's tempered), A and y of both batches, sd)."""
    rng = np.random.default_rng(7)
    A1, A2 = rng.normal(size=(4, 2)), rng.normal(size=(4, 2))
    theta, s = np.array([0.4, -0.7]), 0.3
    y1 = A1 @ theta + s * rng.normal(size=4)
    y2 = A2 @ theta + s * rng.normal(size=4)
    prior = JointPrior({f"t{j}": TruncatedNormal(0.0, 1.0, -20.0, 20.0) for j in range(2)})
    A, y = np.vstack([A1, A2]), np.concatenate([y1, y2])
    old = PartedLinearGaussian(A1, y1, s, [(0, 1), (2, 3)])
    new = PartedLinearGaussian(A, y, s, [(0, 1), (2, 3), (4, 5), (6, 7)], base=[1, 1, 0, 0])
    return prior, old, new, A, y, s
