"""A case's ``[sampler]`` table: the TMCMC settings as a case writes and stores them.

:class:`SamplerSettings` validates the table, fills what it leaves to its move scheme
(:func:`scm_core.inference.tmcmc.moves.form_defaults`) and holds every field of
:class:`~scm_core.inference.TMCMCSettings`, generated from its declaration (type, default,
description, choices and bounds: :func:`_case_field`), so that a stored case keeps every
setting its samples depend on; :data:`TUNING_BEFORE` is what a case stored before then ran with.
Declared here are only the keys that are not TMCMCSettings fields (``n_samples``,
``batch_size``) and where a case differs from the sampler: its default move scheme
(:data:`~scm_core.inference.tmcmc.moves.STUDY_MOVES`), the keys its move scheme fills
(:data:`FORM_KEYS`, null until filled) and :data:`CASE_LIMITS`.
"""

from __future__ import annotations

import dataclasses
import typing
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, create_model, model_validator
from pydantic.fields import FieldInfo

from scm_core.inference.tmcmc.moves import MOVES, STUDY_MOVES, form_defaults
from scm_core.inference.tmcmc.types import TMCMCSettings

__all__ = [
    "CASE_KEYS",
    "CASE_LIMITS",
    "FORM_KEYS",
    "TUNING",
    "TUNING_BEFORE",
    "WASTE_FREE_STEPS_BEFORE",
    "SamplerSettings",
    "StrictModel",
]


class StrictModel(BaseModel):
    """A case's tables: unknown keys refused, immutable, no inf or NaN."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class _SamplerFields(StrictModel):
    """TMCMC settings (see :class:`scm_core.inference.TMCMCSettings`, whose fields are this
    table's keys with their descriptions, defaults and bounds, less where a case differs).

    ``moves``: "waste-free" (the default: the accelerated accurate form), "resample-move" (the
    unaccelerated accurate form) or "leader" (the paper's form). ``n_steps`` (waste-free),
    ``delayed_acceptance``, ``surrogate_steps``, ``surrogate_jumps``, ``proposal_scale`` and
    ``resampling`` left out (or null) take the move scheme's defaults, filled in and stored with
    the case (:func:`scm_core.inference.tmcmc.moves.form_defaults`): for "waste-free" 4 moves per
    chain, surrogate transitions of 40 inner steps with population jumps, the log walk and
    multinomial resampling; for "resample-move" and "leader" plain steps in the parameters and
    systematic resampling (their ``n_steps`` left null adapts per stage).

    ``batch_size``: chains per batch handed to the ``map`` (None: chosen by the runner; does
    not change the results). ``max_stages``: stop (status "max_stages") after that many
    tempering stages. ``early_rejection``: stop simulating a proposal's datasets once they
    cannot lift it over the acceptance threshold (exact, same samples; see
    :mod:`scm_core.inference.early_rejection`). ``delayed_acceptance``: move with a surrogate
    of the responses fitted on the stage's starting states before simulating (exact, other
    samples; :mod:`scm_core.inference.surrogate`): ``surrogate_steps`` Metropolis steps on the
    surrogate per model run (1: Christen & Fox's delayed acceptance), of which a fraction
    ``surrogate_jumps`` are independence proposals from the population's t
    (:mod:`scm_core.inference.population_jump`). ``proposal_scale``:
    "log" walks the log of every strictly positive parameter (exact; SCM's multiplicative
    trade-offs become straight ridges, :mod:`scm_core.inference.walk_space`). ``resampling``:
    "systematic" (less resampling noise) or "multinomial" (independent draws); either way the
    evidence's standard error is the genealogy estimate (docs/calibration.md, "How sure is
    log Z").

    The sampler's finer tuning (``min_steps``, ``beta0``, ``surrogate_neighbors`` ...: the
    other fields of TMCMCSettings, :data:`TUNING`) is a key too, so that a case's stored form
    (:meth:`CaseDefinition.to_dict`) holds every setting its samples depend on: a later change
    of a default in code changes no stored study. A stored case from before these were stored
    is read with the values they had then (:data:`TUNING_BEFORE`,
    :meth:`CaseDefinition.from_stored`).
    """

    n_samples: int = Field(2000, ge=10, description="Samples per stage.")
    batch_size: int | None = Field(None, ge=1)

    _filled: frozenset[str] = PrivateAttr(default=frozenset())

    @model_validator(mode="after")
    def _form_defaults(self) -> SamplerSettings:
        """Fill what the case left to its move scheme; ``model_fields_set`` keeps what the
        case gave (:meth:`CaseDefinition.with_changes` merges onto that alone)."""
        filled = []
        for key, value in form_defaults(self.moves).items():
            if getattr(self, key) is None:
                self.__dict__[key] = value
                filled.append(key)
        self._filled = frozenset(filled)
        return self

    @model_validator(mode="after")
    def _valid_tuning(self) -> _SamplerFields:
        self.tmcmc_settings()  # TMCMCSettings' own checks (ValueError names the field)
        return self

    def __eq__(self, other: object) -> bool:
        # equal settings are equal whether the case named them or its move scheme filled them
        if not isinstance(other, _SamplerFields):
            return NotImplemented
        return self.model_dump() == other.model_dump()

    def __hash__(self) -> int:
        return hash(tuple(sorted(self.model_dump().items())))

    def given(self) -> dict[str, Any]:
        """The settings the case gave (not the ones its move scheme filled in)."""
        keys = set(self.model_fields_set) - self._filled
        return self.model_dump(include=keys, exclude_none=True)

    def tmcmc_settings(self) -> TMCMCSettings:
        """The sampler's settings (every key the move scheme fills is filled by now)."""
        return TMCMCSettings(**{f.name: getattr(self, f.name) for f in _SETTINGS})


_SETTINGS = dataclasses.fields(TMCMCSettings)
_BY_NAME = {f.name: f for f in _SETTINGS}
_TYPES = typing.get_type_hints(TMCMCSettings)

#: the TMCMCSettings fields a case's [sampler] table had before its tuning was stored (names
#: only: each is generated from its TMCMCSettings field), in the order a case lists them
CASE_KEYS = (
    "moves",
    "n_steps",
    "max_stages",
    "target_cov",
    "early_rejection",
    "delayed_acceptance",
    "surrogate_steps",
    "surrogate_jumps",
    "proposal_scale",
    "resampling",
)

#: TMCMCSettings' other fields: a case's finer tuning
TUNING = tuple(f.name for f in _SETTINGS if f.name not in CASE_KEYS)

#: the keys a case may leave to its move scheme (null until form_defaults fills them)
FORM_KEYS = frozenset(key for moves in MOVES for key in form_defaults(moves))

#: a case's bounds beyond the sampler's own
CASE_LIMITS: dict[str, dict[str, Any]] = {"surrogate_steps": {"le": 100}}


def _case_field(f: dataclasses.Field) -> tuple[Any, FieldInfo]:
    """The [sampler] key of TMCMCSettings' field ``f``: its type (its ``choices`` a Literal),
    default, description and bounds from the field's declaration; a case's default move
    scheme is :data:`STUDY_MOVES`, and a key of :data:`FORM_KEYS` is optional and null."""
    limits = {k: v for k, v in f.metadata.items() if k not in ("doc", "choices")}
    limits.update(CASE_LIMITS.get(f.name, {}))
    choices = f.metadata.get("choices")
    kind: Any = Literal[choices] if choices else _TYPES[f.name]
    default = STUDY_MOVES if f.name == "moves" else f.default
    if f.name in FORM_KEYS:
        kind, default = kind | None, None
    return kind, Field(default, description=f.metadata.get("doc"), **limits)


#: the tuning's values before stored cases held it (its code defaults until then): what a case
#: stored without it ran with. A record of the past, like a migration: never edit it when a
#: default changes (issue 43)
TUNING_BEFORE: dict[str, int | float] = {
    "min_steps": 10,
    "max_steps": 50,
    "initial_steps": 20,
    "move_probability": 0.99,
    "beta0": 0.2,
    "target_acceptance": 0.234,
    "beta_gain": 1.0,
    "beta_min": 0.02,
    "beta_max": 3.0,
    "stall_tol": 1e-8,
    "stall_stages": 3,
    "surrogate_neighbors": 50,
    "surrogate_smoothing": 1e-3,
    "surrogate_memory": 20_000,
}

#: moves per chain of a waste-free case stored before the form's default was stored with it
#: (WASTE_FREE_STEPS until then); a record of the past, like TUNING_BEFORE
WASTE_FREE_STEPS_BEFORE = 4

SamplerSettings = create_model(
    "SamplerSettings",
    __base__=_SamplerFields,
    __module__=__name__,
    __doc__=_SamplerFields.__doc__,
    **{name: _case_field(_BY_NAME[name]) for name in (*CASE_KEYS, *TUNING)},
)
