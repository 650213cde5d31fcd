"""One-line messages from pydantic validation errors (the first error, with its location).

Shared by the case reader, the simulator-configuration prechecks, the CLI overrides and the
sensitivity studies, so that every caller names the field the same way.
"""

from __future__ import annotations

from typing import Any

from pydantic import ValidationError

#: location elements pydantic adds for the member of a union it tried (not the user's path)
_UNION_TAGS = ("float", "int", "bool", "str")


def first_error(exc: ValidationError) -> tuple[list[str], str, dict[str, Any]]:
    """(location parts, message without pydantic's "Value error, " prefix, the raw error) of
    the first error of ``exc``."""
    err = exc.errors()[0]
    loc = [str(p) for p in err.get("loc", ()) if str(p) not in _UNION_TAGS]
    message = str(err.get("msg", "invalid value")).removeprefix("Value error, ")
    return loc, message, err


def one_line(exc: ValidationError | ValueError, where: str = "") -> str:
    """``"loc: message"`` of the first error (a plain ``ValueError``: its text), the location
    prefixed by ``where`` when given (``where.loc``)."""
    if not isinstance(exc, ValidationError):
        text = " ".join(str(exc).split())
        return f"{where}: {text}" if where else text
    loc, message, _ = first_error(exc)
    path = ".".join(p for p in (where, ".".join(loc)) if p)
    return f"{path}: {message}" if path else message


def quoted(value: Any, width: int = 40) -> str:
    """``repr(value)`` for a message, cut to about ``width`` characters with the full length
    said: an error quotes enough of the offending input to find it, never the whole of a huge
    cell, header or key (``'xxxxx...' (10485760 characters)``)."""
    if isinstance(value, str) and len(value) > width:
        return f"{value[:width]!r}... ({len(value)} characters)"
    text = repr(value)
    return text if len(text) <= width else f"{text[: width - 3]}..."
