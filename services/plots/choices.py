"""What the figures show, decided without matplotlib (the dashboard's pages choose with it
before anything is drawn): the paper's parameter pairs and a run's mean contact width."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

__all__ = ["PAPER_PAIRS", "default_pairs", "mean_b_eff"]

#: pairs of the paper's Figures 6 (case 1) and 7-8 (cases 2), in order of preference
PAPER_PAIRS = (("k_c", "k_phi"), ("n", "phi"), ("phi", "J"), ("n", "R"))


def default_pairs(names: Sequence[str], limit: int = 3) -> list[tuple[str, str]]:
    """The paper's pairs among ``names`` (k_c-k_phi, n-phi, phi-J or n-R), else consecutive
    pairs of the non-sigma parameters; at most ``limit``."""
    pairs = [p for p in PAPER_PAIRS if p[0] in names and p[1] in names]
    if "J" in names:
        pairs = [p for p in pairs if p != ("n", "R")] + [p for p in pairs if p == ("n", "R")]
    physical = [n for n in names if not n.startswith(("sigma_", "z_offset"))]
    for a, b in itertools.pairwise(physical):
        if len(pairs) >= limit:
            break
        if (a, b) not in pairs and (b, a) not in pairs:
            pairs.append((a, b))
    return pairs[:limit]


def mean_b_eff(sim: Any) -> float | None:
    """Mean effective contact width b_eff (m) of a simulated run (an ``SWTResult``) over its
    second half: the width of the k* = k_c / b_eff + k_phi line (eq. (11)). None without one."""
    if sim is None:
        return None
    b = sim.series["b_eff"]
    t = sim.series["t"]
    sel = b[(t >= t[-1] / 2) & (b > 0)]
    return float(sel.mean()) if sel.size else None
