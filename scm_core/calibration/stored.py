"""A study's arrays of responses as stored before a response was declared (issue 70's lateral
force): read with it NaN, "not simulated".

A stage's population, plan and batch results keep the responses the likelihood returned, one
group of k per dataset (:data:`scm_core.signals.responses.RESPONSES`, in order). A study stored
with fewer per dataset (three: F, T, z) reads with the later ones NaN
(:func:`~scm_core.signals.responses.widened`); no dataset of such a study measured them, so no
likelihood term reads them, and the delayed-acceptance surrogate fits only the columns the
likelihood reads (``StudyModel.response_outputs``): the study goes on bit for bit as it would
have.
"""

from __future__ import annotations

import dataclasses
from typing import TypeVar

import numpy as np

from scm_core.signals.responses import widened

__all__ = ["with_all_responses"]

T = TypeVar("T")


def with_all_responses(obj: T, groups: int) -> T:
    """``obj`` (a dataclass: a stage state, plan or batch result) with every array field named
    ``*responses`` read as :func:`widened` over ``groups`` (the study's datasets); ``obj``
    itself when nothing is to widen."""
    changes = {}
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if f.name.endswith("responses") and isinstance(value, np.ndarray) and value.ndim == 2:
            wide = widened(value, groups)
            if wide is not value:
                changes[f.name] = wide
    return dataclasses.replace(obj, **changes) if changes else obj  # type: ignore[type-var]
