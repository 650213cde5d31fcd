"""``KEY=VALUE`` overrides of the simulator's three configuration types."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import click
from pydantic import BaseModel, ValidationError

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry, resolve_rig
from scm_core.validation_text import first_error

CONFIG_TYPES: tuple[type[BaseModel], ...] = (SoilParams, WheelGeometry, RigConfig)


def set_option(help: str):
    """The repeatable ``--set KEY=VALUE`` option of the commands that build one simulator
    configuration (its values reach the command as ``overrides``)."""
    return click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", help=help)


class OverrideError(ValueError):
    """A bad KEY=VALUE; the message is one line and names the key."""


def known_keys() -> dict[str, type[BaseModel]]:
    """Every settable key and the config type that owns it."""
    return {name: cls for cls in CONFIG_TYPES for name in cls.model_fields}


def parse_overrides(items: Iterable[str]) -> dict[type[BaseModel], dict[str, Any]]:
    """Split ``KEY=VALUE`` strings by owning config; values stay strings for pydantic to coerce."""
    owners = known_keys()
    out: dict[type[BaseModel], dict[str, Any]] = {cls: {} for cls in CONFIG_TYPES}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise OverrideError(f"expected KEY=VALUE, got {item!r}")
        if key not in owners:
            raise OverrideError(f"unknown key {key!r}; known keys: {', '.join(sorted(owners))}")
        out[owners[key]][key] = value.strip()
    return out


def build_configs(items: Iterable[str]) -> tuple[SoilParams, WheelGeometry, RigConfig]:
    """Validated (soil, wheel, rig) from the paper's defaults plus the overrides."""
    grouped = parse_overrides(items)
    built = []
    for cls in CONFIG_TYPES:
        try:
            built.append(cls.model_validate(grouped[cls]))
        except ValidationError as exc:
            raise OverrideError(_one_line(exc, grouped[cls])) from None
    soil, wheel, rig = built
    try:
        resolve_rig(wheel, rig)  # kinematics and derived numerics must be consistent
    except ValueError as exc:
        raise OverrideError(str(exc)) from None
    return soil, wheel, rig


def _one_line(exc: ValidationError, given: dict[str, Any]) -> str:
    parts, msg, _ = first_error(exc)
    loc = ".".join(parts)
    if loc:
        return f"invalid value for {loc}={given.get(loc, '?')!s}: {msg}"
    return msg
