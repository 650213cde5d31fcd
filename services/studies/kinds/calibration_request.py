"""The request of a calibration, ``POST /studies`` (the calibration kind's create route, see
:class:`~.base.KindHttp`): a preset or a case document with overrides on stored datasets, as
``runs`` repeated runs, or ``update_of`` a completed calibration (a posterior update, kind
:mod:`.update`). The model only; :func:`build_case` makes the case it asks for."""

from __future__ import annotations

import types
import typing
from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, create_model

from scm_core.calibration import CaseDefinition, SamplerSettings
from scm_core.seeds import SEED_MAX
from services.limits import INT32_MAX, INT64_MAX

from ..intake import base_case, with_overrides
from ..request_model import PRESET_OR_CASE, RequestModel

__all__ = ["RUNS_MAX", "SAMPLER_OVERRIDES", "StudyCreate", "build_case"]

#: ids: what a BIGINT column holds; counts and sizes: what an INTEGER column holds
ID_MAX = INT64_MAX
COUNT_MAX = INT32_MAX
#: most studies of one run group (POST /studies with runs)
RUNS_MAX = 64
#: the case's top-level settings a request may override
TOP_OVERRIDES = ("name", "seed", "likelihood")


class _StudyFields(RequestModel):
    """A new study: a preset name or a full case document, the stored datasets to fit, and
    optional overrides of the case's settings; or ``update_of`` a completed calibration with
    new datasets (a posterior update, paper section 5.3: the case is the earlier study's)."""

    model_config = ConfigDict(json_schema_extra=PRESET_OR_CASE)

    preset: str | None = Field(
        None, description="A preset: 'quick', or the paper's '1', '2a', '2b'."
    )
    case: dict[str, Any] | None = Field(
        None, description="A case document (the TOML case file as JSON); data.files is ignored."
    )
    update_of: int | None = Field(
        None,
        ge=0,
        le=ID_MAX,
        description="Update the posterior of this completed calibration with the new "
        "dataset_ids: stage 0 is its final population and only the new datasets' likelihood "
        "is tempered. Its log_evidence is then log Z(new | old); the total is in its result.",
    )
    dataset_ids: list[Annotated[int, Field(ge=1, le=ID_MAX)]] = Field(
        default_factory=list, description="Stored datasets (POST /datasets), likelihood order."
    )
    name: str | None = Field(None, min_length=1, max_length=200)
    seed: int | None = Field(None, ge=0, le=SEED_MAX)
    likelihood: Literal["normalized", "gaussian"] | None = None
    batch_size: int | None = Field(
        None,
        ge=1,
        le=COUNT_MAX,
        description="Chains per work batch (at most; shorter at a stage's end).",
    )
    runs: int = Field(
        1,
        ge=1,
        le=RUNS_MAX,
        description="Repeated runs: this many studies with the seeds seed, seed + 1, ... (a "
        "run group; the answer is the first, with the group's ids in 'runs'); GET /pooled "
        "on them gives R-hat across the runs and a convergence verdict.",
    )


#: the case's [sampler] settings a request may override (null: the case's); their types,
#: bounds and descriptions are SamplerSettings', counts capped at the service's limit
SAMPLER_OVERRIDES = (
    "n_samples",
    "moves",
    "n_steps",
    "max_stages",
    "early_rejection",
    "delayed_acceptance",
)


def _override(name: str) -> tuple[Any, Any]:
    """An optional request field overriding the case's sampler setting ``name``."""
    field = SamplerSettings.model_fields[name]
    kind = field.annotation
    if typing.get_origin(kind) in (typing.Union, types.UnionType):  # X | None: X
        kind = next(a for a in typing.get_args(kind) if a is not type(None))
    bounds = [*field.metadata, *([Field(le=COUNT_MAX)] if kind is int else [])]
    typed = Annotated[(kind, *bounds)] if bounds else kind
    return typed | None, Field(None, description=field.description)


StudyCreate = create_model(
    "StudyCreate",
    __base__=_StudyFields,
    __module__=__name__,
    __doc__=_StudyFields.__doc__,
    **{name: _override(name) for name in SAMPLER_OVERRIDES},
)


def build_case(body: Any) -> CaseDefinition:
    """The case of a request (a :data:`StudyCreate`): the preset or the case document, with
    the overrides applied."""
    sampler = {k: getattr(body, k) for k in SAMPLER_OVERRIDES if getattr(body, k) is not None}
    top = {k: getattr(body, k) for k in TOP_OVERRIDES if getattr(body, k) is not None}
    return with_overrides(base_case(body.preset, body.case), top, sampler)
