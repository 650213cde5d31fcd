"""Why a model run failed, in words: the simulator's status (docs/simulator.md, "Statuses") or
a configuration the simulator refuses (a calibrated radius that leaves no room for the
grousers...). One list for the sampler's counts (:class:`scm_core.inference.Failures`), the
screening's and every message that reports failed runs.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from scm_core.simulator import STATUS_NAMES

__all__ = [
    "INVALID",
    "INVALID_CODE",
    "READ_MORE",
    "REASONS",
    "describe_failures",
    "failure_counts",
    "failure_of",
    "reasons_text",
]

#: the reason of a run whose configuration could not be built (nothing was simulated)
INVALID = "invalid_configuration"

#: every reason a run can fail for, in the order messages list them
REASONS = (*STATUS_NAMES[1:], INVALID)

#: a screening's status code of an invalid configuration (else the index in STATUS_NAMES)
INVALID_CODE = -1

_WORDS = {
    "bottomed_out": "bottomed out",
    "nonpositive_stiffness": "non-positive stiffness",
    "unstable": "unstable",
    INVALID: "invalid configuration",
}

#: where a reader finds what each reason means
READ_MORE = 'docs/simulator.md, "Statuses"'


def failure_of(status: str) -> str:
    """A run's failure reason from its simulator status ("" for "ok")."""
    return "" if status == "ok" else str(status)


def failure_counts(status: ArrayLike) -> dict[str, int]:
    """Failed runs by reason from a screening's status codes (:data:`INVALID_CODE`, else the
    index of the simulator status)."""
    codes, counts = np.unique(np.asarray(status, dtype=np.int64), return_counts=True)
    names = {INVALID_CODE: INVALID, **dict(enumerate(STATUS_NAMES))}
    return {names[int(c)]: int(k) for c, k in zip(codes, counts, strict=True) if c != 0}


def reasons_text(failed: int, by: Mapping[str, int]) -> str:
    """ "3 bottomed out, 1 unstable" for ``failed`` runs counted ``by`` reason (in
    :data:`REASONS` order; runs a model gave no reason for as "k for no reason given"); "" when
    no reason is known."""
    order = {r: i for i, r in enumerate(REASONS)}
    parts = [
        f"{k} {_WORDS.get(r, r.replace('_', ' '))}"
        for r, k in sorted(by.items(), key=lambda rk: (order.get(rk[0], len(order)), rk[0]))
        if k
    ]
    rest = failed - sum(by.values())
    if rest > 0 and parts:
        parts.append(f"{rest} for no reason given")
    return ", ".join(parts)


def describe_failures(failed: int, by: Mapping[str, int]) -> str:
    """ "4 failed: 3 bottomed out, 1 unstable" ("4 failed" when no reason is known); "" when
    none failed."""
    if failed <= 0:
        return ""
    why = reasons_text(failed, by)
    return f"{failed} failed" + (f": {why}" if why else "")
