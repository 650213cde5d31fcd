"""Which stored studies are runs of one calibration (their agreement, R-hat, means something)."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from services.store import StudyRecord

__all__ = ["why_not_runs"]


def _case_apart_from_seed(case: Mapping[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in case.items() if k not in ("seed", "name")}


def _differences(a: Mapping[str, Any], b: Mapping[str, Any], prefix: str = "") -> list[str]:
    """The keys (dotted, one level into tables) whose values differ, with both values."""
    out = []
    for key in sorted(set(a) | set(b)):
        x, y = a.get(key), b.get(key)
        if x == y:
            continue
        if isinstance(x, Mapping) and isinstance(y, Mapping) and not prefix:
            out += _differences(x, y, f"{key}.")
        else:
            out.append(f"{prefix}{key} {_shown(key, a)} vs {_shown(key, b)}")
    return out


def _shown(key: str, doc: Mapping[str, Any]) -> str:
    """A value in a difference: "absent", or its JSON, at most 40 characters."""
    if key not in doc:
        return "absent"
    text = json.dumps(doc[key])
    return text if len(text) <= 40 else text[:37] + "..."


def why_not_runs(studies: Sequence[StudyRecord]) -> str | None:
    """None when ``studies`` are runs of one calibration (the same case but for its seed and
    name, on the same datasets), whose agreement (R-hat) means something; else why not, in
    words."""
    first = studies[0]
    base = _case_apart_from_seed(first.case)
    for s in studies[1:]:
        if s.kind != first.kind or sorted(s.dataset_ids) != sorted(first.dataset_ids):
            return (
                f"studies {first.id} and {s.id} are calibrations of different data, not runs "
                "of one calibration"
            )
        diff = _differences(base, _case_apart_from_seed(s.case))
        if diff:
            shown = "; ".join(diff[:3]) + ("; ..." if len(diff) > 3 else "")
            return (
                f"studies {first.id} and {s.id} differ in more than their seed ({shown}): "
                "different calibrations, not runs of one"
            )
    return None
