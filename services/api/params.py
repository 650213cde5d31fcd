"""Path parameters with the range a database column holds: an id out of it names nothing
(answered 404 by the validation handler, as for any id that does not exist)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Path

from services.limits import INT32_MAX, INT64_MAX

StudyId = Annotated[int, Path(ge=0, le=INT64_MAX, description="A study's id.")]
DatasetId = Annotated[int, Path(ge=0, le=INT64_MAX, description="A dataset's id.")]
StageIndex = Annotated[
    int,
    Path(
        ge=-INT32_MAX,
        le=INT32_MAX,
        description="A stage's index (0: the prior draws); negative counts from the last (-1).",
    ),
]

#: path parameters whose out-of-range values answer 404 (resource named in the message)
NOT_FOUND_PARAMS = {"study_id": "study", "dataset_id": "dataset", "stage": "stage"}
