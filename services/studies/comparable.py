"""Which stored studies are runs of one calibration (their agreement, R-hat, means something),
and the model classes a set of calibrations falls into, compared by their runs' log evidence
(:mod:`scm_core.calibration.comparison`)."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from scm_core.calibration.comparison import Comparison, ModelEvidence, compare_models
from services.store import StudyRecord

from .intake import group_name

__all__ = ["compare_studies", "model_classes", "why_not_runs"]


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


def model_classes(studies: Sequence[StudyRecord]) -> list[list[StudyRecord]]:
    """``studies`` grouped into model classes: each group the runs of one calibration (the same
    kind, datasets and case but for seed and name), in the order of its first study."""
    groups: list[list[StudyRecord]] = []
    for s in studies:
        for g in groups:
            if why_not_runs([g[0], s]) is None:
                g.append(s)
                break
        else:
            groups.append([s])
    return groups


def compare_studies(
    studies: Sequence[StudyRecord],
) -> tuple[Comparison, dict[str, list[int]]]:
    """(the model classes of completed calibrations of the same data compared by their runs'
    log evidence, each class's study ids by its name). ValueError in words (naming
    ``study_ids``) when they are calibrations of different data, all runs of one calibration,
    or a study has no log evidence."""
    first = studies[0]
    for s in studies[1:]:
        if sorted(s.dataset_ids) != sorted(first.dataset_ids):
            raise ValueError(
                f"study_ids: studies {first.id} and {s.id} are calibrations of different data; "
                "their evidences are of different data and a Bayes factor between them means "
                "nothing"
            )
    for s in studies:
        if s.log_evidence is None:
            raise ValueError(f"study_ids: study {s.id} has no log evidence")
    groups = model_classes(studies)
    if len(groups) < 2:
        raise ValueError(
            "study_ids: these are all runs of one calibration; a comparison needs at least two "
            "model classes (calibrations that differ in more than their seed)"
        )
    classes, members = [], {}
    for g in groups:
        ids = ", ".join(str(s.id) for s in g)
        name = (
            f"{group_name(g[0].name)} (studies {ids})"
            if len(g) > 1
            else f"{g[0].name} (study {ids})"
        )
        members[name] = [s.id for s in g]
        classes.append(
            ModelEvidence(name, tuple(float(s.log_evidence) for s in g), tuple(_se(s) for s in g))
        )
    return compare_models(classes), members


def _se(study: StudyRecord) -> float:
    var = study.log_evidence_var
    return float(var) ** 0.5 if var is not None and var > 0 else 0.0
