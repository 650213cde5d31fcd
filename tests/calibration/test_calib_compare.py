"""Model comparison over repeated runs (issue 71, part 3): Bayes factors against exact evidences,
the interval's coverage, Welch's test, Kass & Raftery's words, and ``scm-calib compare``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from scm_core.calibration.comparison import (
    ModelEvidence,
    bayes_factor,
    compare_models,
    evidence_words,
)
from scm_core.inference import JointPrior, TMCMCSettings, TruncatedNormal, run_tmcmc

RNG = np.random.default_rng(7)
THETA = np.array([1.0, -0.8, 0.6])
S = 0.2
#: two linear-Gaussian model classes for the same six observations: A (the one that made them)
#: and B (its design without the last column: exact ln B 14.06); theta ~ N(0, I) under both
A = RNG.normal(size=(6, 3))
Y = A @ THETA + S * RNG.normal(size=6)
B = A.copy()
B[:, 2] = 0.0


def _exact_log_z(design: np.ndarray) -> float:
    """log N(y; 0, S^2 I + X X^T): the evidence of y = X theta + N(0, S^2), theta ~ N(0, I)."""
    return float(stats.multivariate_normal(np.zeros(6), S * S * np.eye(6) + design @ design.T)
                 .logpdf(Y))  # fmt: skip


def _likelihood(design: np.ndarray):
    norm = -0.5 * Y.size * math.log(2.0 * math.pi * S * S)

    def log_l(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pred = X @ design.T
        return norm - 0.5 * np.sum((pred - Y) ** 2, axis=1) / S**2, pred

    return log_l


PRIOR = JointPrior({f"t{j}": TruncatedNormal(0.0, 1.0, -10.0, 10.0) for j in range(3)})
SETTINGS = TMCMCSettings()


def _runs(name: str, design: np.ndarray, seeds) -> ModelEvidence:
    res = [run_tmcmc(_likelihood(design), PRIOR, 300, seed=s, settings=SETTINGS) for s in seeds]
    return ModelEvidence(
        name, tuple(r.log_evidence for r in res), tuple(r.log_evidence_se for r in res)
    )


def test_the_bayes_factor_of_runs_covers_the_exact_one() -> None:
    """Four runs of each class: the data's own design (A) over the one missing a column (B) by
    the exact ln B (14.06), inside the 95 % interval, decided, 'very strong'."""
    exact = _exact_log_z(A) - _exact_log_z(B)
    assert exact > 5.0
    comparison = compare_models([_runs("B", B, range(4)), _runs("A", A, range(10, 14))])
    assert [m.name for m in comparison.models] == ["A", "B"]
    (bf,) = comparison.against_best
    assert abs(bf.log_bf - exact) < bf.half_width
    assert bf.decided and bf.line().endswith(f"(95 % interval +-{bf.half_width:.2f})")
    assert "very strong" in bf.line()


def test_the_same_class_twice_is_not_decided() -> None:
    """Two groups of runs of one class: ln B exactly 0, which the interval covers: 'not
    decided'."""
    bf = bayes_factor(_runs("one", A, range(3)), _runs("two", A, range(3, 6)))
    assert abs(bf.log_bf) < bf.half_width
    assert not bf.decided and "not decided" in bf.line()


@pytest.mark.slow
def test_the_interval_covers_the_exact_bayes_factor_95_percent_of_the_time() -> None:
    """Coverage over 40 independent comparisons of three runs each (seeds disjoint): the 95 %
    interval of ln B should hold the exact value in 95 % of them; 40 comparisons have a
    binomial sd of 3.4 %, so at least 34 of 40 (85 %, three sd below)."""
    exact = _exact_log_z(A) - _exact_log_z(B)
    hits = 0
    for r in range(40):
        bf = bayes_factor(
            _runs("A", A, range(6 * r, 6 * r + 3)), _runs("B", B, range(6 * r + 3, 6 * r + 6))
        )
        hits += abs(bf.log_bf - exact) < bf.half_width
    print(f"{hits} of 40 intervals hold the exact ln B {exact:.3f}")
    assert hits >= 34


@pytest.mark.parametrize("seed", range(5))
def test_decided_is_welchs_two_sided_test_at_5_percent(seed: int) -> None:
    """With several runs a side, 'decided' is Welch's unequal-variance t test (scipy's) of the
    two classes' run means rejecting equality at 5 %, two-sided."""
    rng = np.random.default_rng(seed)
    za = rng.normal(0.0, 1.0, size=3 + seed)
    zb = rng.normal(1.2, 2.0, size=4)
    bf = bayes_factor(
        ModelEvidence("a", tuple(za), (0.1,) * za.size),
        ModelEvidence("b", tuple(zb), (0.1,) * zb.size),
    )
    welch = stats.ttest_ind(za, zb, equal_var=False)
    assert bf.log_bf == pytest.approx(abs(za.mean() - zb.mean()), rel=1e-12)
    assert bf.decided == (welch.pvalue < 0.05)


def test_words_follow_kass_and_raftery() -> None:
    """Kass & Raftery (1995) on the ln B scale: 0-1, 1-3, 3-5, above 5."""
    assert evidence_words(0.5) == "not worth more than a bare mention"
    assert evidence_words(2.0) == "positive"
    assert evidence_words(4.0) == "strong"
    assert evidence_words(12.0) == "very strong"


def test_one_run_uses_its_reported_error_and_a_normal_interval() -> None:
    bf = bayes_factor(ModelEvidence("a", (10.0,), (0.2,)), ModelEvidence("b", (9.0,), (0.3,)))
    assert math.isinf(bf.dof) and bf.se == pytest.approx(math.hypot(0.2, 0.3))
    assert bf.half_width == pytest.approx(1.959964 * bf.se, rel=1e-6)


@pytest.mark.parametrize(
    ("models", "needle"),
    [
        ([ModelEvidence("a", (1.0,), (0.1,))], "at least two"),
        ([ModelEvidence("a", (1.0,), (0.1,)), ModelEvidence("a", (2.0,), (0.1,))], "distinct"),
    ],
)
def test_bad_comparisons_are_refused(models, needle) -> None:
    with pytest.raises(ValueError, match=needle):
        compare_models(models)
    with pytest.raises(ValueError, match="finite"):
        ModelEvidence("c", (math.nan,), (0.1,))


@pytest.mark.slow  # the command end to end (four calibrations); the logic stays fast
def test_the_command_runs_cases_and_reads_results_folders(tmp_path: Path) -> None:
    """`compare` on two case files runs each twice (run groups under OUT, as `calibrate
    --runs 2`), ranks the classes by the mean of their runs' ln Z and writes compare.json;
    given the run groups' folders instead it reads them and gives the same file; one source,
    or a file that is not a case, is refused in one line."""
    from test_calib_cli import CASE
    from test_calib_cli import run_cli as _cli

    synth = _cli("synth", "--set", "phi=27", "--set", "J=0.004", "--set", "dx=0.015", "--set",
                 "dt=0.05", "--duration", "8", "--ramp", "1", "--seed", "3", "--out", "log.csv",
                 cwd=tmp_path)  # fmt: skip
    assert synth.returncode == 0, synth.stderr
    (tmp_path / "wide.toml").write_text(CASE.replace('name = "tiny"', 'name = "wide"'))
    narrow = CASE.replace('name = "tiny"', 'name = "narrow"').replace(
        "mean = 30.0, sd = 5.7", "mean = 22.0, sd = 1.0"
    )
    (tmp_path / "narrow.toml").write_text(narrow)
    proc = _cli("compare", "wide.toml", "narrow.toml", "--runs", "2", "--out", "cmp", "--quiet",
                cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    by_name = {m["name"]: m for m in doc["models"]}
    assert set(by_name) == {"wide", "narrow"}
    for name in ("wide", "narrow"):
        runs = [
            json.loads((tmp_path / "cmp" / name / f"run_{k}" / "summary.json").read_text())
            for k in (1, 2)
        ]
        assert by_name[name]["run_log_evidence"] == [r["log_evidence"] for r in runs]
        assert by_name[name]["log_evidence"] == pytest.approx(
            np.mean([r["log_evidence"] for r in runs]), rel=1e-12
        )
    best = doc["models"][0]["name"]
    assert doc["bayes_factors"][0]["better"] == best
    assert doc["bayes_factors"][0]["verdict"] in proc.stdout.replace("\n", " ") or (
        doc["bayes_factors"][0]["verdict"][:30] in proc.stdout
    )
    again = _cli("compare", "cmp/wide", "cmp/narrow", "--out", "cmp2", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert json.loads((tmp_path / "cmp2" / "compare.json").read_text()) == doc
    for args, needle in (
        (("compare", "wide.toml"), "at least two"),
        (("compare", "log.csv", "cmp/wide"), "not a case file"),
    ):
        bad = _cli(*args, cwd=tmp_path)
        assert bad.returncode == 2 and needle in bad.stderr, bad.stderr
        assert "Traceback" not in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
