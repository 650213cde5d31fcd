"""The base of request bodies: what the OpenAPI document declares is what is accepted.

Pydantic's lax mode converts across JSON types (``false`` to a seed of 0, ``0`` to a flag,
``"5"`` to 5) where JSON Schema, and so the OpenAPI document, calls the value invalid; its
strict mode refuses what JSON Schema allows (``1e3`` is an integer there, and a JSON array a
tuple). :class:`RequestModel` keeps lax parsing but first refuses a value whose JSON type the
field's type does not admit, naming the field: booleans only for ``bool``, numbers (not
booleans, not strings) for ``int`` (integral ones) and ``float``, and so on inside lists,
tuples and dicts. Unknown fields are refused too (a typo must not pass silently).
"""

from __future__ import annotations

import types
import typing
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationInfo, field_validator

__all__ = ["PRESET_OR_CASE", "RequestModel", "json_type_error"]

#: a study is made from exactly one of a preset name and a case document (the other absent or
#: null; a calibration's request may name the study it updates instead); the server's check,
#: in the OpenAPI document
PRESET_OR_CASE: dict[str, Any] = {
    "oneOf": [
        {"required": ["preset"], "properties": {"preset": {"type": "string"}}},
        {"required": ["case"], "properties": {"case": {"type": "object"}}},
        {"required": ["update_of"], "properties": {"update_of": {"type": "integer"}}},
    ]
}

_JSON_NAMES = {bool: "a boolean", int: "an integer", float: "a number", str: "a string"}


def _json_name(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int | float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list | tuple):
        return "an array"
    return "an object"


def _admits(annotation: Any, value: Any) -> bool | None:
    """Whether ``annotation`` admits ``value``'s JSON type (None: not a type checked here)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _admits(typing.get_args(annotation)[0], value)
    if origin in (typing.Union, types.UnionType):
        verdicts = [_admits(a, value) for a in typing.get_args(annotation)]
        if any(v is True for v in verdicts):
            return True
        return False if all(v is False for v in verdicts) else None
    if annotation is type(None):
        return value is None
    if annotation is bool:
        return isinstance(value, bool)
    if annotation is int:
        if isinstance(value, bool):
            return False
        return isinstance(value, int) or (isinstance(value, float) and value.is_integer())
    if annotation is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if annotation is str:
        return isinstance(value, str)
    if origin in (list, tuple) and isinstance(value, list | tuple):
        args = [a for a in typing.get_args(annotation) if a is not Ellipsis]
        if not args:
            return True
        per_item = args if origin is tuple and len(args) == len(value) else [args[0]] * len(value)
        return all(_admits(a, v) is not False for a, v in zip(per_item, value, strict=False))
    if origin in (list, tuple):
        return False
    if origin is dict:
        if not isinstance(value, dict):
            return False
        args = typing.get_args(annotation)
        return not args or all(_admits(args[1], v) is not False for v in value.values())
    return None


def _declared(annotation: Any) -> Any:
    """``annotation`` without Annotated and an optional None."""
    while typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return _declared(args[0])
    return annotation


def json_type_error(annotation: Any, value: Any) -> str | None:
    """Why ``value`` (parsed JSON) is not of a JSON type ``annotation`` admits, or None; an
    array's first bad item is named by its index."""
    if _admits(annotation, value) is not False:
        return None
    base = _declared(annotation)
    if typing.get_origin(base) in (list, tuple) and isinstance(value, list | tuple):
        args = [a for a in typing.get_args(base) if a is not Ellipsis]
        for i, item in enumerate(value):
            arg = args[i] if typing.get_origin(base) is tuple and len(args) > 1 else args[0]
            problem = json_type_error(arg, item)
            if problem is not None:
                return f"item {i}: {problem}"
    wanted = _JSON_NAMES.get(base)
    if wanted is None and typing.get_origin(base) in (list, tuple):
        wanted = "an array"
    elif wanted is None and typing.get_origin(base) is dict:
        wanted = "an object"
    if wanted is None:
        return f"{_json_name(value)} is not of the declared type"
    return f"must be {wanted}, not {_json_name(value)}"


class RequestModel(BaseModel):
    """A request body: unknown fields refused, JSON types as declared (module docstring)."""

    model_config = ConfigDict(extra="forbid")

    @field_validator("*", mode="before")
    @classmethod
    def _json_type_as_declared(cls, value: Any, info: ValidationInfo) -> Any:
        field = cls.model_fields.get(info.field_name or "")
        if field is not None:
            problem = json_type_error(field.annotation, value)
            if problem is not None:
                raise ValueError(problem)
        return value
