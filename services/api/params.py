"""Path parameters with the range a database column holds: an id out of it names nothing
(answered 404 by the validation handler, as for any id that does not exist)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import HTTPException, Path, Query

from scm_core.validation_text import quoted
from services.limits import INT32_MAX, INT64_MAX
from services.store.models import STUDY_STATUSES

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


_ANY_STATUS = "|".join(STUDY_STATUSES)
#: what ``?status=`` accepts: statuses separated by commas, spaces around them and empty
#: items ignored (the pattern of the parameter in the OpenAPI document)
STATUS_PATTERN = rf"^ *(?:(?:{_ANY_STATUS}) *)?(?:, *(?:(?:{_ANY_STATUS}) *)?)*$"


def status_query(what: str) -> Any:
    """The ``?status=`` parameter of a list of ``what``."""
    return Query(
        description=f"Filter {what}: one status or several, comma-separated "
        f"({', '.join(STUDY_STATUSES)}).",
        json_schema_extra={"pattern": STATUS_PATTERN},
    )


def parse_statuses(status: str | None) -> list[str] | None:
    """``?status=a,b`` as a list (None: all); 422 naming ``query.status`` for an unknown one.
    Items are separated by commas; spaces around them and empty items are ignored
    (:data:`STATUS_PATTERN`)."""
    items = [s.strip(" ") for s in (status or "").split(",")]
    unknown = [s for s in items if s and s not in STUDY_STATUSES]
    if unknown:
        raise HTTPException(
            422,
            f"query.status: unknown status {unknown[0]!r}; one of {', '.join(STUDY_STATUSES)}",
        )
    return [s for s in items if s] or None


def parse_id_list(items: list[str], field: str, limit: int = 1000) -> list[int]:
    """Ids from query items, each one id or several comma-separated (spaces and empty items
    around commas ignored), in order; 422 naming ``field`` for anything else, and "no study"
    for an id no row can have (0, or beyond what the database can hold)."""
    ids: list[int] = []
    for item in items:
        parts = [p.strip(" ") for p in item.split(",")]
        if not any(parts):
            raise HTTPException(422, f"{field}: no study id in {quoted(item)}")
        for part in filter(None, parts):
            if not (part.isascii() and part.isdigit()):
                raise HTTPException(422, f"{field}: not a study id: {quoted(part)}")
            if len(part.lstrip("0")) > 19 or not 0 < int(part) <= INT64_MAX:  # ids: 1..BIGINT
                raise HTTPException(422, f"{field}: no study with id {part[:40]}")
            ids.append(int(part))
    if len(ids) > limit:
        raise HTTPException(422, f"{field}: {len(ids)} studies, at most {limit}")
    return ids
