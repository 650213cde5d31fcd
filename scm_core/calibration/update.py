"""The likelihood of a posterior update (paper section 5.3: "successive posterior distributions
should not be very different", so updating is cheap).

An update starts from the population of p(theta | old data) and tempers only L(new data); the
old datasets' likelihood is the base density b (see :mod:`scm_core.inference.tmcmc_stage`), so
the stages target prior x L(old) x L(new)^p, p from 0 to 1, and the evidence accumulated is
Z(new | old) = Z(old and new) / Z(old).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .model import StudyModel

__all__ = ["UpdateLikelihood"]


class UpdateLikelihood:
    """``model`` over the old datasets (the first ``n_old``) and then the new ones: X (m, d) ->
    (log L(new) (m,), responses (m, 3 n_datasets), log L(old) (m,)). One simulator run per
    point covers all datasets, as in a joint calibration. Picklable."""

    def __init__(self, model: StudyModel, n_old: int) -> None:
        if not 0 < n_old < model.n_datasets:
            raise ValueError(
                f"an update needs old and new datasets, got {n_old} old of {model.n_datasets}"
            )
        self.model = model
        self.n_old = int(n_old)

    def __call__(
        self, X: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        means, _ = self.model.simulate_means(X)
        sigma = self.model.sigmas(X)
        n = self.model.n_datasets
        old = self.model.log_likelihood_from_means(means, sigma, range(self.n_old))
        new = self.model.log_likelihood_from_means(means, sigma, range(self.n_old, n))
        return new, means.reshape(X.shape[0], -1), old
