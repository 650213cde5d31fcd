"""Failed model runs counted by reason (issue 69: "2900 model runs (4 failed)" said nothing of
why). A likelihood may give, with its output, why each failed run failed; every stage then
counts its failures by reason (``StageState.failed_by``), whichever path ran the model: the
full evaluation, early rejection's part-by-part runs, a surrogate's correction or stage 0.

The target: theta ~ N(0, I) in 2-D, y = theta + N(0, 0.5^2) observed at (0.8, -0.8), so a good
share of the posterior's proposals cross the lines where the "model" fails: part 0 fails with
"too_far" where theta_0 > 1, part 1 with "too_low" where theta_1 < -1 (both: the first part in
run order names it). The failures are a function of the point, so every count can be checked
against the points the chains proposed: here, that the reasons add up to the failed runs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest

from scm_core.inference import Failures, JointPrior, TMCMCSettings, TruncatedNormal, run_tmcmc
from scm_core.inference.tmcmc.types import StageCounts

Y = np.array([0.8, -0.8])
S = 0.5
PRIOR = JointPrior({f"t{j}": TruncatedNormal(0.0, 1.0, -10.0, 10.0) for j in range(2)})
REASON = ("too_far", "too_low")


class FailingParts:
    """Two parts (one coordinate each); part k fails beyond its line with REASON[k]."""

    part_order = (1, 0)
    part_in_base = (False, False)
    response_inputs = (0, 1)

    def __init__(self, give_reasons: bool = True) -> None:
        self.give_reasons = give_reasons

    def _fails(self, X: np.ndarray, k: int) -> np.ndarray:
        return X[:, 0] > 1.0 if k == 0 else X[:, 1] < -1.0

    def run_part(self, X: np.ndarray, k: int):
        bad = self._fails(X, k)
        pred = np.where(bad, np.nan, X[:, k])
        term = -0.5 * ((Y[k] - pred) / S) ** 2 - math.log(S) - 0.5 * math.log(2 * math.pi)
        why = np.where(bad, REASON[k], "")
        return (term, pred[:, None], why) if self.give_reasons else (term, pred[:, None])

    def part_bound(self, X: np.ndarray, k: int) -> np.ndarray:
        return np.full(X.shape[0], -math.log(S) - 0.5 * math.log(2 * math.pi))

    def assemble(self, X: np.ndarray, responses: Sequence[np.ndarray]):
        return self._output(X, np.concatenate(list(responses), axis=1))

    def _output(self, X: np.ndarray, R: np.ndarray):
        r = (Y - R) / S
        ll = np.sum(-0.5 * r * r, axis=1) - 2 * (math.log(S) + 0.5 * math.log(2 * math.pi))
        return np.where(np.isnan(ll), -np.inf, ll), R

    def from_responses(self, X: np.ndarray, R: np.ndarray):
        return self._output(X, R)

    def __call__(self, X: np.ndarray):
        ll, R = self._output(X, np.stack([self.run_part(X, k)[1][:, 0] for k in (0, 1)], axis=1))
        if not self.give_reasons:
            return ll, R
        why = np.full(X.shape[0], "", dtype=object)
        for k in reversed(self.part_order):  # the first failing part in run order names it
            why = np.where(self._fails(X, k), REASON[k], why)
        return ll, R, None, why.astype(str)


FORMS = {
    "full evaluation": TMCMCSettings(early_rejection=False),
    "early rejection": TMCMCSettings(early_rejection=True),
    "surrogate transitions": TMCMCSettings(
        moves="waste-free", delayed_acceptance=True, surrogate_steps=5, surrogate_jumps=0.1
    ),
}


@pytest.mark.parametrize("form", list(FORMS))
def test_every_failed_run_is_counted_with_its_reason(form: str) -> None:
    res = run_tmcmc(FailingParts(), PRIOR, 400, seed=5, settings=FORMS[form])
    assert res.status == "completed"
    for s in res.stages:
        assert s.failed_by.total == s.failed_runs, (s.stage, s.failed_by, s.failed_runs)
        assert {r for r, _ in s.failed_by.counts} <= set(REASON)
    total = res.failed_by
    assert total.total == res.n_failed_runs > 0
    # both lines are crossed: the prior puts 16 % of its mass beyond each, and the chains
    # propose across them all the way to the posterior (mean 0.64, -0.64, sd 0.45)
    assert dict(total.counts).keys() == set(REASON)
    # a stored stage reads back with its reasons
    again = type(res.stages[-1]).from_dict(res.stages[-1].to_dict())
    assert again.failed_by == res.stages[-1].failed_by


def test_a_likelihood_that_gives_no_reasons_still_counts_its_failures() -> None:
    res = run_tmcmc(FailingParts(give_reasons=False), PRIOR, 400, seed=5)
    assert res.n_failed_runs > 0 and res.failed_by.total == 0


def test_counts_add_and_read_the_names_stored_before() -> None:
    a = StageCounts(model_runs=3, failed_runs=2, failed_by=Failures.of(["x", "y"]))
    b = StageCounts(model_runs=1, failed_runs=1, failed_by=Failures.of({"x": 1}))
    both = a.plus(b)
    assert (both.model_runs, both.failed_runs) == (4, 3)
    assert both.failed_by.to_dict() == {"x": 2, "y": 1}
    # a stage stored before the counters had one name each (issue 72)
    old = StageCounts.from_dict({"inner_proposed": 7, "jump_accepted": 2})
    assert (old.surrogate_steps, old.population_jumps_accepted) == (7, 2)
