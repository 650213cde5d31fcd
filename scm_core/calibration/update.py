"""The likelihood of a posterior update (paper section 5.3: "successive posterior distributions
should not be very different", so updating is cheap).

An update starts from the population of p(theta | old data) and tempers only L(new data); the
old datasets' likelihood is the base density b (see :mod:`scm_core.inference.tmcmc.stage`), so
the stages target prior x L(old) x L(new)^p, p from 0 to 1, and the evidence accumulated is
Z(new | old) = Z(old and new) / Z(old).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from scm_core.inference.tmcmc.loop import PopulationStart
from scm_core.inference.tmcmc.stage import StageState
from scm_core.signals.responses import N_RESPONSES, widened

from .model import StudyModel

__all__ = ["UpdateLikelihood"]


class UpdateLikelihood:
    """``model`` over the old datasets (the first ``n_old``) and then the new ones: X (m, d) ->
    (log L(new) (m,), responses (m, N_RESPONSES n_datasets), log L(old) (m,), failure reasons
    (m,)). One
    simulator run per point covers all datasets, as in a joint calibration. Picklable."""

    def __init__(self, model: StudyModel, n_old: int) -> None:
        if not 0 < n_old < model.n_datasets:
            raise ValueError(
                f"an update needs old and new datasets, got {n_old} old of {model.n_datasets}"
            )
        self.model = model
        self.n_old = int(n_old)

    def __call__(
        self, X: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.str_]]:
        """(log L(new), responses, log L(old), why each failed run failed) at X (m, d)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        means, _, failure = self.model.simulate(X)
        return (*self._output(X, means), self.model.first_failure(failure))

    def _output(
        self, X: NDArray[np.float64], means: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        sigma = self.model.sigmas(X)
        n = self.model.n_datasets
        old = self.model.log_likelihood_from_means(means, sigma, range(self.n_old))
        new = self.model.log_likelihood_from_means(means, sigma, range(self.n_old, n))
        return new, means.reshape(X.shape[0], -1), old

    def start(self, final: StageState) -> PopulationStart:
        """Stage 0 of the update: the earlier study's final population ``final``, stage 1
        tuned from its beta and acceptance rate (see ``initial_state``), the old datasets'
        parts taken from its responses (not run again; bit-identical to running them)."""
        known = None if final.responses is None else self.base_parts(final.responses)
        tuning = (float(final.beta), float(final.acceptance_rate))
        return PopulationStart(np.asarray(final.samples, dtype=float), tuning, known)

    def base_parts(self, responses: ArrayLike) -> dict[int, NDArray[np.float64]]:
        """The old datasets' parts {k: lab-side means (m, N_RESPONSES)} from the responses
        (m, N_RESPONSES n_old) the earlier study returned at its population (its datasets are
        the first n_old, in order): stage 0 of the update then runs the new datasets only
        (``known_parts`` of :func:`~scm_core.inference.tmcmc.stage.evaluate_points`), with the
        same result. A study stored before the later responses were declared returned fewer
        per dataset (F, T, z): those read as NaN (:func:`~scm_core.signals.responses.widened`),
        so that stage 0 runs its old datasets again, as it does any known part with a
        non-finite response: the same bits, at the cost of a full stage 0."""
        R = np.asarray(responses, dtype=float)
        k_r = N_RESPONSES
        if R.ndim == 2 and R.shape[1] < k_r * self.n_old and R.shape[1] % self.n_old == 0:
            R = widened(R, self.n_old)
        if R.ndim != 2 or R.shape[1] < k_r * self.n_old:
            raise ValueError(
                f"responses of shape {R.shape} do not hold {self.n_old} datasets' {k_r} means"
            )
        return {k: R[:, k_r * k : k_r * (k + 1)] for k in range(self.n_old)}

    # surrogate (delayed acceptance): the model's responses
    @property
    def response_inputs(self) -> tuple[int, ...]:
        return self.model.response_inputs

    @property
    def response_outputs(self) -> tuple[int, ...]:
        return self.model.response_outputs

    def from_responses(
        self, X: NDArray[np.float64], R: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n = self.model.n_datasets
        R = widened(R, n).reshape(X.shape[0], n, N_RESPONSES)
        return self._output(X, R)

    # parts (early rejection): the model's datasets; the old ones form the base density
    @property
    def part_order(self) -> tuple[int, ...]:
        return self.model.part_order

    @property
    def part_in_base(self) -> tuple[bool, ...]:
        return tuple(k < self.n_old for k in range(self.model.n_datasets))

    def run_part(
        self, X: NDArray[np.float64], k: int
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.str_]]:
        return self.model.run_part(X, k)

    def part_bound(self, X: NDArray[np.float64], k: int) -> NDArray[np.float64]:
        return self.model.part_bound(X, k)

    def assemble(
        self, X: NDArray[np.float64], responses: Sequence[NDArray[np.float64]]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return self._output(X, np.stack([np.asarray(r, dtype=float) for r in responses], axis=1))
