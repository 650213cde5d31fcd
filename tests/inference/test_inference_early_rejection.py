"""Early rejection across likelihood parts (issue 12) against targets with exact answers.

Early rejection decides each Metropolis move as the full evaluation would, so a run with it must
give the *same bits* as a run without it (samples, likelihoods, evidence) while running fewer
parts. The targets are the exact-answer problems of test_inference_tmcmc_accuracy and
test_inference_update with their data split into parts (observations in groups, like datasets
of a study); each is also checked against its exact answer with the tolerances of those modules
(their docstrings give the Monte Carlo error budgets).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from parted_targets import (
    A5,
    PRIOR5,
    S5,
    Y5,
    PartedBimodal,
    PartedLinearGaussian,
    exact_linear,
    parted_5d,
    update_problem,
)
from scipy import stats

from scm_core.inference import (
    JointPrior,
    PopulationStart,
    TMCMCSettings,
    TruncatedNormal,
    Uniform,
    run_tmcmc,
)
from scm_core.inference.early_rejection import evaluate_staged, is_parted
from scm_core.inference.tmcmc.stage import evaluate_points, first_occurrences, initial_state

LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def _pair(f, prior: JointPrior, seed: int, moves: str = "resample-move", **kwargs):
    """(run without, run with early rejection)."""
    off = run_tmcmc(
        f, prior, seed=seed, settings=TMCMCSettings(moves=moves, early_rejection=False), **kwargs
    )
    on = run_tmcmc(
        f, prior, seed=seed, settings=TMCMCSettings(moves=moves, early_rejection=True), **kwargs
    )
    return off, on


def assert_same_bits(off, on) -> None:
    assert len(off.stages) == len(on.stages)
    for a, b in zip(off.stages, on.stages, strict=True):
        assert np.array_equal(a.samples, b.samples)
        assert np.array_equal(a.log_likelihood, b.log_likelihood)
        assert np.array_equal(a.log_prior, b.log_prior)
        assert np.array_equal(a.responses, b.responses, equal_nan=True)
        assert a.exponent == b.exponent and a.log_evidence == b.log_evidence
        assert (a.accepted, a.proposals, a.model_runs) == (b.accepted, b.proposals, b.model_runs)
        # every part a run without early rejection made was either run or saved
        assert b.part_runs + b.part_runs_saved == a.part_runs
        assert a.part_runs_saved == a.early_rejections == 0


def _totals(res) -> tuple[int, int, int]:
    return (
        sum(s.part_runs for s in res.stages),
        sum(s.part_runs_saved for s in res.stages),
        sum(s.early_rejections for s in res.stages),
    )


# --- 5-D linear-Gaussian (as test_inference_tmcmc_accuracy), 8 observations in 4 parts -------


@pytest.mark.parametrize("moves", ["resample-move", "leader"])
def test_linear_gaussian_5d_same_bits_fewer_runs_exact_answer(moves: str) -> None:
    f = parted_5d()
    assert is_parted(f)
    off, on = _pair(f, PRIOR5, seed=0, moves=moves)
    assert_same_bits(off, on)
    runs_off, saved_off, _ = _totals(off)
    runs_on, saved_on, early = _totals(on)
    print(f"5-D {moves}: part runs {runs_off} -> {runs_on}, early rejections {early}")
    assert saved_off == 0 and saved_on > 0 and early > 0
    assert runs_on + saved_on == runs_off
    # stage 0 runs every part of every sample: 2000 x 4
    assert on.stages[0].part_runs == 2000 * 4
    if moves == "resample-move":
        # the exact answer, tolerances of test_linear_gaussian_5d (0.1 sd, 10 %, 0.25 nat)
        mean, sd, log_z = exact_linear(A5, Y5, S5)
        assert np.abs(on.samples.mean(axis=0) - mean).max() < 0.1 * sd.min()
        assert np.abs(on.samples.std(axis=0) / sd - 1.0).max() < 0.10
        assert abs(on.log_evidence - log_z) < 0.25


# --- 1-D conjugate Gaussian, two observations in two parts ------------------------------------


def test_conjugate_1d_two_parts_exact_answer() -> None:
    A = np.array([[1.0], [1.0]])
    y = np.array([0.52, 0.48])
    s = 0.01 * math.sqrt(2.0)  # two data of sd 0.01 sqrt 2: the posterior of one datum of sd 0.01
    prior = JointPrior({"theta": TruncatedNormal(0.0, 1.0, -20.0, 20.0)})
    f = PartedLinearGaussian(A, y, s, [(0,), (1,)])
    off, on = _pair(f, prior, seed=0)
    assert_same_bits(off, on)
    assert _totals(on)[2] > 0
    mean, sd, log_z = exact_linear(A, y, s)
    assert abs(on.samples[:, 0].mean() - mean[0]) < 0.1 * sd[0]
    assert abs(on.samples[:, 0].std() / sd[0] - 1.0) < 0.10
    assert abs(on.log_evidence - log_z) < 0.25


# --- posterior piled against a prior bound, two observations ----------------------------------


def test_posterior_piled_against_bound_two_parts() -> None:
    """theta ~ U(0, 1), two observations 1.2 of sd 0.3 sqrt 2: the posterior is N(1.2, 0.3^2)
    truncated to [0, 1], as in test_posterior_piled_against_bound_matches_truncated_normal."""
    mu, sd = 1.2, 0.3
    f = PartedLinearGaussian(
        np.array([[1.0], [1.0]]), np.array([mu, mu]), sd * math.sqrt(2.0), [(0,), (1,)]
    )
    prior = JointPrior({"theta": Uniform(0.0, 1.0)})
    off, on = _pair(f, prior, seed=0)
    assert_same_bits(off, on)
    exact = stats.truncnorm((0.0 - mu) / sd, (1.0 - mu) / sd, loc=mu, scale=sd)
    x = on.samples[:, 0]
    assert abs(x.mean() - exact.mean()) < 0.1 * exact.std()
    assert stats.kstest(x, exact.cdf).statistic < 0.05


# --- bimodal: a product of two independent 2-D mixtures -----------------------------------


def test_bimodal_product_mode_masses_and_evidence() -> None:
    prior = JointPrior({f"x{j}": Uniform(-5.0, 5.0) for j in range(4)})
    off, on = _pair(PartedBimodal(), prior, seed=0)
    assert_same_bits(off, on)
    assert _totals(on)[2] > 0
    # both mixtures lie > 6 sd inside the box: Z = 1 / 10^4 (to ~1e-9); tolerance as the
    # 4-D bimodal test of test_inference_tmcmc_accuracy (0.3 nat)
    assert abs(on.log_evidence + 4.0 * math.log(10.0)) < 0.3
    # each pair's low mode holds 0.1 of the mass (0.05: as that test)
    for k in range(2):
        assert abs(np.mean(on.samples[:, 2 * k : 2 * k + 2].sum(axis=1) < 0.0) - 0.1) < 0.05


# --- a posterior update: the old parts in the base density ------------------------------------


def test_update_with_base_parts_same_bits_and_exact_answer() -> None:
    """As test_inference_update: y1 then y2 (4 observations each, 2-D); the update's old
    observations are base parts (weight 1), the new ones tempered."""
    prior, old_f, f, A, y, s = update_problem()
    old = run_tmcmc(old_f, prior, 4000, seed=3)
    off, on = _pair(f, prior, seed=4, n_samples=4000, start=PopulationStart(old.samples))
    assert_same_bits(off, on)
    assert _totals(on)[2] > 0
    mean, sd, log_z = exact_linear(A, y, s)
    # 4000 samples: standard error of a mean ~0.03 sd, of an sd ~2 %; 0.1 sd and 7 % (~3 se);
    # total log evidence 0.2 nat (two runs of sd ~0.06 each at 4000 samples)
    assert np.all(np.abs(on.samples.mean(axis=0) - mean) < 0.1 * sd)
    assert np.all(np.abs(on.samples.std(axis=0) / sd - 1.0) < 0.07)
    assert abs(old.log_evidence + on.log_evidence - log_z) < 0.2


def test_update_stage0_reuses_the_old_parts_same_bits() -> None:
    """Stage 0 of an update given the old parts' responses at the earlier population (its own
    responses there) runs only the new parts and gives the same bits as running them all; a
    known part with a non-finite response is run again."""
    prior, old_f, f, _, _, _ = update_problem()
    old = run_tmcmc(old_f, prior, 1000, seed=3)
    known = {k: old.final.responses[:, 2 * k : 2 * k + 2] for k in range(2)}
    full = run_tmcmc(f, prior, 1000, seed=4, start=PopulationStart(old.samples))
    reused = run_tmcmc(f, prior, 1000, seed=4, start=PopulationStart(old.samples, None, known))
    for a, b in zip(full.stages, reused.stages, strict=True):
        assert np.array_equal(a.samples, b.samples)
        assert np.array_equal(a.log_likelihood, b.log_likelihood)
        assert np.array_equal(a.log_prior, b.log_prior)
        assert np.array_equal(a.responses, b.responses)
        assert a.log_evidence == b.log_evidence
    assert full.stages[0].part_runs == 4 * 1000 and reused.stages[0].part_runs == 2 * 1000
    X = old.samples[:5]
    bad = {0: known[0][:5].copy(), 1: known[1][:5]}
    bad[0][2, 1] = np.nan
    f.calls.clear()
    ev = evaluate_points(X, f, bad)
    assert sorted(f.calls) == [(0, 5), (2, 5), (3, 5)] and ev.part_runs == 15
    assert np.array_equal(ev.log_likelihood, evaluate_points(X, f).log_likelihood)


def test_update_stage0_runs_a_repeated_point_once_same_bits() -> None:
    """An earlier population repeats points (a rejected move keeps its state): stage 0 runs
    each distinct point once, for any batching, and builds the state a full evaluation of every
    row builds; its model_runs and part runs count the distinct points."""
    prior, old_f, f, _, _, _ = update_problem()
    old = run_tmcmc(old_f, prior, 400, seed=3)
    rows = np.random.default_rng(5).integers(0, 400, 400)  # with replacement: ~63 % distinct
    X = old.samples[rows]
    known = {k: old.final.responses[rows, 2 * k : 2 * k + 2] for k in range(2)}
    distinct = len({row.tobytes() for row in X})
    assert distinct < 300
    settings = TMCMCSettings()
    runs = []
    for batch_size in (None, 1, 7, 64):
        runs.append(
            run_tmcmc(
                f,
                prior,
                400,
                seed=4,
                settings=settings,
                batch_size=batch_size,
                start=PopulationStart(X, None, known),
            )
        )
    s0 = runs[0].stages[0]
    assert s0.model_runs == distinct and s0.part_runs == 2 * distinct
    reference = initial_state(prior, X, [evaluate_points(X, f)], 4, settings)
    for name in ("log_likelihood", "log_prior", "responses", "samples"):
        assert np.array_equal(getattr(s0, name), getattr(reference, name))
    for other in runs[1:]:
        for a, b in zip(runs[0].stages, other.stages, strict=True):
            assert a.equals(b)
    f.calls.clear()
    copies = first_occurrences(X) != np.arange(400)
    ev = evaluate_points(X, f, known, copies)
    assert sorted(f.calls) == [(2, distinct), (3, distinct)] and ev.model_runs == distinct
    assert np.isnan(ev.log_likelihood[copies]).all()


# --- the staged evaluation itself ---------------------------------------------------------


def test_staged_evaluation_runs_parts_in_order_and_never_drops_a_reachable_proposal() -> None:
    rng = np.random.default_rng(0)
    f = parted_5d(order=[2, 0, 3, 1])
    X = rng.normal(size=(400, 5))
    full, _ = f(X)
    for p in (0.05, 1.0):
        # thresholds around the tempered values: half of the proposals reachable
        threshold = p * full + rng.normal(0.0, 5.0, size=400)
        f.calls.clear()
        ev = evaluate_staged(f, X, threshold, p)
        assert [k for k, _ in f.calls] == [2, 0, 3, 1]
        # a dropped proposal is one whose full value misses the threshold
        assert np.all(p * full[ev.rejected] < threshold[ev.rejected])
        assert not np.any(ev.rejected & ev.complete)
        assert np.array_equal(ev.rejected | ev.complete, np.ones(400, dtype=bool))
        ll, _ = ev.output
        assert np.array_equal(ll, full[ev.complete])  # bit-identical to the full evaluation
        assert ev.part_runs + ev.part_runs_saved == 400 * 4
        assert ev.part_runs == sum(n for _, n in f.calls)
    # a threshold of -inf drops nothing; +inf drops everything after the first part
    ev = evaluate_staged(f, X, np.full(400, -np.inf), 1.0)
    assert ev.complete.all() and ev.part_runs_saved == 0
    ev = evaluate_staged(f, X, np.full(400, np.inf), 1.0)
    assert ev.rejected.all() and ev.part_runs == 400 and ev.output is None


def test_a_wrapped_likelihood_keeps_its_parts_and_responses() -> None:
    """The CLI's stop check and the worker's timer wrap the study likelihood; a wrapper that
    hid run_part or from_responses would silently turn both accelerations off."""
    from scm_core.inference.surrogate import supports_surrogate
    from scm_core.inference.wrapped import WrappedLikelihood

    calls = []

    class Counting(WrappedLikelihood):
        def around(self, evaluate):
            calls.append(1)
            return evaluate()

    f = parted_5d()
    w = Counting(f)
    assert is_parted(w) and supports_surrogate(w)
    assert w.part_order == f.part_order and w.response_inputs == f.response_inputs
    settings = TMCMCSettings(early_rejection=True)
    a = run_tmcmc(f, PRIOR5, 300, seed=1, settings=settings)
    b = run_tmcmc(w, PRIOR5, 300, seed=1, settings=settings)
    assert np.array_equal(a.samples, b.samples)
    assert sum(s.early_rejections for s in b.stages) > 0
    assert len(calls) > 0  # every evaluation went through the wrapper
