"""Do repeated runs of one study agree? R-hat and ESS across runs, and a verdict.

The paper repeats TMCMC three times and pools the runs (section 5.2, Fig. 9); PyMC's
``sample_smc`` runs several independent SMC chains and reports R-hat over them. Here each run's
final population (its posterior samples, in population order) is one chain of an ArviZ
posterior, and ArviZ computes, per parameter, the rank-normalised split R-hat and the bulk and
tail effective sample sizes (Vehtari, Gelman, Simpson, Carpenter & Buerkner 2021, "Rank-
normalization, folding, and localization: an improved R-hat", Bayesian Analysis 16(2)). Runs
that sample the same posterior give R-hat near 1; a parameter whose runs disagree (a ridge the
sampler did not cross, a mode one run missed) gives more. The verdict follows Vehtari et al.'s
recommendation: converged when every R-hat is at most 1.01.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scm_core.arviz_import import arviz

__all__ = ["RHAT_LIMIT", "ParameterAgreement", "RunsVerdict", "diagnose_runs"]

#: largest R-hat of a converged parameter (Vehtari et al. 2021)
RHAT_LIMIT = 1.01
#: bulk and tail ESS per run below which the verdict warns (Vehtari et al. 2021: 100 per chain)
ESS_PER_RUN = 100


@dataclass(frozen=True)
class ParameterAgreement:
    """One parameter over the runs: R-hat, bulk and tail ESS, pooled mean and sd, and each
    run's mean."""

    name: str
    rhat: float
    ess_bulk: float
    ess_tail: float
    mean: float
    sd: float
    run_means: tuple[float, ...]


@dataclass(frozen=True)
class RunsVerdict:
    """The agreement of K runs: per parameter (:class:`ParameterAgreement`), each run's log
    evidence and its standard error, and the verdict."""

    parameters: tuple[ParameterAgreement, ...]
    log_evidence: tuple[float, ...]
    log_evidence_se: tuple[float, ...]
    draws_per_run: int

    @property
    def runs(self) -> int:
        return len(self.log_evidence)

    @property
    def disagreeing(self) -> tuple[str, ...]:
        """Parameters whose R-hat exceeds :data:`RHAT_LIMIT` (or is not finite)."""
        return tuple(p.name for p in self.parameters if not p.rhat <= RHAT_LIMIT)

    @property
    def few_effective(self) -> tuple[str, ...]:
        """Parameters with a bulk or tail ESS below :data:`ESS_PER_RUN` per run."""
        low = ESS_PER_RUN * self.runs
        return tuple(p.name for p in self.parameters if not min(p.ess_bulk, p.ess_tail) >= low)

    @property
    def converged(self) -> bool:
        return not self.disagreeing

    @property
    def log_evidence_spread(self) -> tuple[float, float]:
        """(sd of the runs' log Z, root mean square of their own standard errors)."""
        z = np.asarray(self.log_evidence)
        se = np.asarray(self.log_evidence_se)
        sd = float(np.std(z, ddof=1)) if z.size > 1 else 0.0
        return sd, float(np.sqrt(np.mean(se * se)))

    def line(self) -> str:
        """The verdict in one line."""
        k = self.runs
        if self.converged:
            worst = max(self.parameters, key=lambda p: p.rhat)
            text = (
                f"converged: R-hat <= {RHAT_LIMIT} for all {len(self.parameters)} parameters "
                f"over {k} runs (largest {worst.rhat:.3f}, {worst.name})"
            )
        else:
            bad = ", ".join(
                f"{p.name} (R-hat {p.rhat:.3f})"
                for p in sorted(self.parameters, key=lambda p: -p.rhat)
                if p.name in self.disagreeing
            )
            text = (
                f"NOT converged: the {k} runs disagree on {bad}; do not use the pooled "
                "posterior (more samples per stage, the accurate form, or a narrower prior)"
            )
        if self.few_effective:
            text += f"; few effective samples for {', '.join(self.few_effective)}"
        sd, se = self.log_evidence_spread
        if k > 1 and sd > 3.0 * se:
            text += f"; log Z scatters by {sd:.3g} between runs, its standard error is {se:.3g}"
        return text

    def to_dict(self) -> dict[str, Any]:
        sd, _ = self.log_evidence_spread
        return {
            "runs": self.runs,
            "draws_per_run": self.draws_per_run,
            "rhat_limit": RHAT_LIMIT,
            "converged": self.converged,
            "disagreeing": list(self.disagreeing),
            "few_effective": list(self.few_effective),
            "verdict": self.line(),
            "parameters": {
                p.name: {
                    "rhat": _json_float(p.rhat),
                    "ess_bulk": _json_float(p.ess_bulk),
                    "ess_tail": _json_float(p.ess_tail),
                    "mean": p.mean,
                    "sd": p.sd,
                    "run_means": list(p.run_means),
                }
                for p in self.parameters
            },
            "log_evidence": list(self.log_evidence),
            "log_evidence_se": list(self.log_evidence_se),
            "log_evidence_sd": sd,
            "log_evidence_mean": float(np.mean(self.log_evidence)),
        }


def _json_float(v: float) -> float | None:
    return v if math.isfinite(v) else None


def diagnose_runs(
    names: Sequence[str],
    samples: Sequence[NDArray[np.float64]],
    log_evidence: Sequence[float],
    log_evidence_se: Sequence[float],
) -> RunsVerdict:
    """The agreement of runs whose final populations are ``samples`` (one (n, d) array per
    run, the same n; columns ``names``) with their log evidences and standard errors. Raises
    ValueError for fewer than two runs, unequal or empty populations or non-finite samples."""
    if len(samples) < 2:
        raise ValueError("R-hat needs at least two runs")
    shapes = {np.shape(s) for s in samples}
    if len(shapes) != 1:
        raise ValueError(f"the runs' populations differ in shape: {sorted(shapes)}")
    chains = np.stack([np.asarray(s, dtype=float) for s in samples])  # (K, n, d)
    _, n, d = chains.shape
    if n < 4 or d != len(names):
        raise ValueError(f"populations of {n} samples of {d} columns for {len(names)} parameters")
    if not np.all(np.isfinite(chains)):
        raise ValueError("a run's population holds non-finite values")
    az = arviz()  # slow to import; only here

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # ArviZ 0.23's notice of its 1.0
        idata = az.from_dict(posterior={name: chains[:, :, j] for j, name in enumerate(names)})
        rhat = az.rhat(idata, method="rank")
        bulk = az.ess(idata, method="bulk")
        tail = az.ess(idata, method="tail")
    params = tuple(
        ParameterAgreement(
            name=name,
            rhat=float(rhat[name]),
            ess_bulk=float(bulk[name]),
            ess_tail=float(tail[name]),
            mean=float(chains[:, :, j].mean()),
            sd=float(chains[:, :, j].std(ddof=1)),
            run_means=tuple(float(m) for m in chains[:, :, j].mean(axis=1)),
        )
        for j, name in enumerate(names)
    )
    return RunsVerdict(
        parameters=params,
        log_evidence=tuple(float(z) for z in log_evidence),
        log_evidence_se=tuple(float(s) for s in log_evidence_se),
        draws_per_run=n,
    )
