"""Repeated trials in the likelihood (``trials = "each"``): a summary of n trials counts as n
tests, checked against scipy's normal density over the trial values read straight from the
CSV (not through our parser's statistics)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from scm_core.calibration import CaseDefinition, CaseError, StudyModel
from scm_core.signals import load_dataset
from scm_core.signals.responses import N_RESPONSES

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SUMMARY = EXAMPLES / "cmu_smooth" / "cmu_smooth_sm050.csv"
LOG = EXAMPLES / "wf34_s020.csv"
SIGMA_F, SIGMA_Z = 1.3, 0.0021  # N, m


def trial_values() -> dict[str, np.ndarray]:
    """The trials' drawbar pull [N] and sinkage [m] as the lab wrote them."""
    with SUMMARY.open(encoding="utf-8") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    return {
        "F": np.array([float(r["drawbar_pull [N]"]) for r in rows]),
        "z": np.array([float(r["sinkage [m]"]) for r in rows]),
    }


def make_case(likelihood: str, trials: str | None) -> CaseDefinition:
    doc = {
        "name": "trials",
        "likelihood": likelihood,
        "responses": ["F", "z"],
        "parameters": {"phi": {"dist": "uniform", "lower": 15.0, "upper": 45.0}},
        "nominal": {"sigma_F": SIGMA_F, "sigma_z": SIGMA_Z},
    }
    if trials is not None:
        doc["trials"] = trials
    return CaseDefinition.from_dict(doc)


def injected_means(rng: np.random.Generator, m: int) -> np.ndarray:
    """Simulated means (m, 1, N_RESPONSES) around the data: F, T (unused), z, Fy (unused)."""
    means = np.zeros((m, 1, N_RESPONSES))
    means[:, 0, 0] = -17.0 + 3.0 * rng.standard_normal(m)
    means[:, 0, 2] = 0.024 + 0.004 * rng.standard_normal(m)
    return means


@pytest.mark.parametrize("likelihood", ["gaussian", "normalized"])
def test_each_trial_is_a_test(likelihood: str) -> None:
    data = load_dataset(SUMMARY)
    model = StudyModel(make_case(likelihood, "each"), [data])
    values = trial_values()
    assert model.n_tests == (len(values["F"]),) == (3,)
    means = injected_means(np.random.default_rng(3), 7)
    sigma = np.tile([SIGMA_F, SIGMA_Z], (7, 1))
    got = model.log_likelihood_from_means(means, sigma)
    for i in range(7):
        expect = 0.0
        for r, col, s in (("F", 0, SIGMA_F), ("z", 2, SIGMA_Z)):
            logpdf = stats.norm.logpdf(values[r], loc=means[i, 0, col], scale=s)
            expect += logpdf.sum()
            if likelihood == "normalized":  # eq. (13)-(15) has no 1/sigma factor
                expect += len(values[r]) * np.log(s)
        assert got[i] == pytest.approx(expect, rel=1e-12, abs=1e-9)


def test_mean_is_one_test_at_the_trial_mean() -> None:
    data = load_dataset(SUMMARY)
    model = StudyModel(make_case("gaussian", None), [data])
    values = trial_values()
    assert model.n_tests == (1,)
    means = injected_means(np.random.default_rng(4), 5)
    sigma = np.tile([SIGMA_F, SIGMA_Z], (5, 1))
    got = model.log_likelihood_from_means(means, sigma)
    expect = stats.norm.logpdf(values["F"].mean(), means[:, 0, 0], SIGMA_F) + stats.norm.logpdf(
        values["z"].mean(), means[:, 0, 2], SIGMA_Z
    )
    np.testing.assert_allclose(got, expect, rtol=1e-12)


def test_a_log_is_one_test_and_the_bound_holds() -> None:
    model = StudyModel(make_case("gaussian", "each"), [load_dataset(LOG), load_dataset(SUMMARY)])
    assert model.n_tests == (1, 3)
    X = np.array([[30.0]])
    sigma = np.array([[SIGMA_F, SIGMA_Z]])
    bound = model.part_bound(X, 1)
    # the bound is reached where the simulated mean is the trial mean, and nowhere exceeded
    at_mean = np.zeros((1, 2, N_RESPONSES))
    at_mean[0, 1] = model.x_exp[1]
    assert model.log_likelihood_from_means(at_mean, sigma, [1])[0] == pytest.approx(bound[0])
    rng = np.random.default_rng(5)
    for _ in range(20):
        means = np.zeros((1, 2, N_RESPONSES))
        means[:, 1:] = injected_means(rng, 1)
        assert model.log_likelihood_from_means(means, sigma, [1])[0] < bound[0]


def test_case_key() -> None:
    default = make_case("gaussian", None)
    assert default.trials == "mean" and "trials" not in default.to_dict()
    assert make_case("gaussian", "mean").fingerprint() == default.fingerprint()
    each = make_case("gaussian", "each")
    assert CaseDefinition.from_dict(each.to_dict()).trials == "each"
    assert each.fingerprint() != default.fingerprint()
    with pytest.raises(CaseError, match=r"^trials: "):
        make_case("gaussian", "all")
