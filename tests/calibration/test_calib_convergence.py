"""R-hat and ESS across runs (scm_core.calibration.convergence) against the classic formulas."""

from __future__ import annotations

import numpy as np
import pytest

from scm_core.calibration.convergence import RHAT_LIMIT, diagnose_runs


def _split_rhat(chains: np.ndarray) -> float:
    """Gelman et al.'s split R-hat (BDA3 eq. 11.4) of chains (K, n), written out here."""
    n = chains.shape[1]
    half = n // 2
    split = np.concatenate([chains[:, :half], chains[:, half : 2 * half]])  # (2K, n/2)
    m = split.shape[1]
    w = split.var(axis=1, ddof=1).mean()
    b = m * split.mean(axis=1).var(ddof=1)
    return float(np.sqrt(((m - 1) / m * w + b / m) / w))


def _runs(shift: float, seed: int = 0, k: int = 4, n: int = 500) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    runs = []
    for r in range(k):
        x = rng.normal(size=(n, 2))
        x[:, 1] = 3.0 + 0.2 * x[:, 1] + (shift * 0.2 if r == 0 else 0.0)  # b: run 0 off by shift sd
        runs.append(x)
    return runs


def test_runs_of_one_posterior_agree() -> None:
    runs = _runs(shift=0.0)
    v = diagnose_runs(("a", "b"), runs, [-1.0, -1.1, -0.9, -1.0], [0.1] * 4)
    chains = np.stack(runs)
    for j, p in enumerate(v.parameters):
        # for normal draws the rank-normalised split R-hat is the classic one (to ~1e-3 at n 500)
        assert p.rhat == pytest.approx(_split_rhat(chains[:, :, j]), abs=3e-3)
        assert p.rhat <= RHAT_LIMIT
        # independent draws: ESS near the 2000 draws (sd of the estimate ~ 5 %)
        assert 1600 < p.ess_bulk < 2500 and 1400 < p.ess_tail < 2600
        assert p.mean == pytest.approx(chains[:, :, j].mean())
    assert v.converged and v.line().startswith("converged")
    assert v.to_dict()["converged"] is True


def test_a_run_off_by_one_posterior_sd_is_named() -> None:
    runs = _runs(shift=1.0)
    v = diagnose_runs(("a", "b"), runs, [-1.0, -1.1, -0.9, -4.0], [0.1] * 4)
    b = v.parameters[1]
    assert b.rhat == pytest.approx(_split_rhat(np.stack(runs)[:, :, 1]), abs=5e-3)
    # two of the eight half-runs 1 sd off: variance of their means 1.5 / 7, R-hat ~ sqrt(1.21)
    assert 1.05 < b.rhat < 1.15
    assert v.disagreeing == ("b",) and not v.converged
    line = v.line()
    assert line.startswith("NOT converged") and "b (R-hat" in line and "a (R-hat" not in line
    assert "log Z scatters" in line  # sd 1.45 against standard errors of 0.1


def test_refuses_what_is_not_two_comparable_runs() -> None:
    runs = _runs(shift=0.0)
    with pytest.raises(ValueError, match="at least two runs"):
        diagnose_runs(("a", "b"), runs[:1], [0.0], [0.1])
    with pytest.raises(ValueError, match="differ in shape"):
        diagnose_runs(("a", "b"), [runs[0], runs[1][:400]], [0.0, 0.0], [0.1, 0.1])
    bad = [r.copy() for r in runs]
    bad[2][5, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        diagnose_runs(("a", "b"), bad, [0.0] * 4, [0.1] * 4)
