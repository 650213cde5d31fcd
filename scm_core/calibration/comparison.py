"""Which model class do the data favour? Log evidences over repeated runs, Bayes factors, words.

Each model class (a case: its simulator options, priors and data) is calibrated K times with
different seeds; each run reports log Z-hat. The runs are independent, so their spread is an
honest measure of a run's error whatever the sampler's mixing, where a single run's reported
standard error can understate it many times (issue 71). A class's log evidence is the mean of
its runs' log Z-hat; its standard error s / sqrt(K) from their sample sd s. The Bayes factor of
class A over class B is B = Z_A / Z_B, on the natural log scale ln B = mean_A - mean_B with the
standard error sqrt(s_A^2 / K_A + s_B^2 / K_B) and Welch-Satterthwaite's degrees of freedom (the
runs' spreads differ between classes). The difference is *decided* when its 95 % interval
(Student's t) leaves out 0; its strength in Kass & Raftery's (1995, JASA 90, "Bayes factors",
table in ln B) words after Jeffreys (1961): below 1 not worth more than a bare mention, 1-3
positive, 3-5 strong, above 5 very strong. A class with one run has only its reported standard
error, which is said as such.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "BayesFactor",
    "Comparison",
    "ModelEvidence",
    "compare_models",
    "evidence_words",
]

#: Kass & Raftery (1995): upper ends of ln B for each strength of evidence
STRENGTHS: tuple[tuple[float, str], ...] = (
    (1.0, "not worth more than a bare mention"),
    (3.0, "positive"),
    (5.0, "strong"),
    (math.inf, "very strong"),
)
#: two-sided level of the interval that decides a difference
LEVEL = 0.95


def evidence_words(log_bf: float) -> str:
    """Kass & Raftery's words for the strength of a Bayes factor ``log_bf`` = ln B >= 0."""
    for upper, words in STRENGTHS:
        if abs(log_bf) < upper:
            return words
    return STRENGTHS[-1][1]


@dataclass(frozen=True)
class ModelEvidence:
    """A model class's runs: ``log_evidence`` ln Z-hat of each run, ``log_evidence_se`` the
    standard error each run reported (used only for a single run)."""

    name: str
    log_evidence: tuple[float, ...]
    log_evidence_se: tuple[float, ...]

    def __post_init__(self) -> None:
        z = np.asarray(self.log_evidence, dtype=float)
        if z.size == 0 or not np.all(np.isfinite(z)):
            raise ValueError(f"{self.name}: needs at least one finite log evidence")
        if len(self.log_evidence_se) != z.size:
            raise ValueError(f"{self.name}: one standard error per run")

    @property
    def runs(self) -> int:
        return len(self.log_evidence)

    @property
    def mean(self) -> float:
        """The class's log evidence: the mean of its runs' ln Z-hat."""
        return float(np.mean(self.log_evidence))

    @property
    def spread(self) -> float:
        """The sample sd of the runs' ln Z-hat (NaN for one run)."""
        return float(np.std(self.log_evidence, ddof=1)) if self.runs > 1 else math.nan

    @property
    def se(self) -> float:
        """Standard error of :attr:`mean`: spread / sqrt(K); one run: its reported error."""
        if self.runs > 1:
            return self.spread / math.sqrt(self.runs)
        return float(self.log_evidence_se[0])


@dataclass(frozen=True)
class BayesFactor:
    """ln B of ``better`` over ``worse`` with its standard error, degrees of freedom (inf for
    a single run on either side: a normal interval), 95 % interval and verdict."""

    better: str
    worse: str
    log_bf: float
    se: float
    dof: float

    @property
    def half_width(self) -> float:
        """Half the 95 % interval of ln B (Student's t with :attr:`dof`)."""
        from scipy import stats  # scipy.stats is slow to import: only when a verdict is made

        q = stats.norm.ppf if math.isinf(self.dof) else (lambda p: stats.t.ppf(p, self.dof))
        return float(q(0.5 + LEVEL / 2.0)) * self.se

    @property
    def decided(self) -> bool:
        """True when the 95 % interval of ln B leaves out 0."""
        return self.log_bf > self.half_width

    def line(self) -> str:
        """The verdict in words."""
        head = f"{self.better} over {self.worse}: ln B = {self.log_bf:.2f} +- {self.se:.2f}"
        if not self.decided:
            return (
                f"{head}: not decided (the 95 % interval, +-{self.half_width:.2f}, includes 0; "
                "more runs or more samples per stage narrow it)"
            )
        return f"{head}: {evidence_words(self.log_bf)} (95 % interval +-{self.half_width:.2f})"

    def to_dict(self) -> dict[str, Any]:
        return {
            "better": self.better,
            "worse": self.worse,
            "log_bayes_factor": self.log_bf,
            "se": self.se,
            "dof": None if math.isinf(self.dof) else self.dof,
            "half_width_95": self.half_width,
            "decided": self.decided,
            "strength": evidence_words(self.log_bf),
            "verdict": self.line(),
        }


def bayes_factor(a: ModelEvidence, b: ModelEvidence) -> BayesFactor:
    """ln B of the class with the larger mean over the other (module doc)."""
    better, worse = (a, b) if a.mean >= b.mean else (b, a)
    va, vb = better.se**2, worse.se**2
    se = math.sqrt(va + vb)
    if better.runs < 2 or worse.runs < 2 or va + vb == 0.0:
        dof = math.inf
    else:  # Welch-Satterthwaite
        dof = (va + vb) ** 2 / (va**2 / (better.runs - 1) + vb**2 / (worse.runs - 1))
    return BayesFactor(better.name, worse.name, better.mean - worse.mean, se, dof)


@dataclass(frozen=True)
class Comparison:
    """Model classes ranked by log evidence, and each one's Bayes factor against the best."""

    models: tuple[ModelEvidence, ...]  # best first
    against_best: tuple[BayesFactor, ...]  # the best over each other class, in rank order

    def lines(self) -> list[str]:
        """The verdicts, one line per class after the best."""
        return [bf.line() for bf in self.against_best]

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": "scm-calib-compare",
            "version": 1,
            "estimate": "mean of the runs' ln Z-hat; se from their spread (one run: its own)",
            "models": [
                {
                    "name": m.name,
                    "runs": m.runs,
                    "log_evidence": m.mean,
                    "se": m.se,
                    "spread": None if math.isnan(m.spread) else m.spread,
                    "run_log_evidence": list(m.log_evidence),
                    "run_log_evidence_se": list(m.log_evidence_se),
                }
                for m in self.models
            ],
            "bayes_factors": [bf.to_dict() for bf in self.against_best],
        }


def compare_models(models: Sequence[ModelEvidence]) -> Comparison:
    """Rank ``models`` (at least two, distinct names) by log evidence and give the best one's
    Bayes factor over each other (module doc). Raises ValueError otherwise."""
    if len(models) < 2:
        raise ValueError("a comparison needs at least two model classes")
    names = [m.name for m in models]
    if len(set(names)) != len(names):
        raise ValueError(f"model classes need distinct names: {', '.join(names)}")
    ranked = tuple(sorted(models, key=lambda m: -m.mean))
    return Comparison(ranked, tuple(bayes_factor(ranked[0], m) for m in ranked[1:]))
