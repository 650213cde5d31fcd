"""Reading the source for the layer tests."""

from __future__ import annotations

import ast
import time
from pathlib import Path


def parse_file(path: Path) -> ast.Module:
    """``ast.parse`` of ``path``, tried again on CPython 3.11's spurious "AST constructor
    recursion depth mismatch" SystemError: the interpreter's AST state is shared between
    threads, and another thread of the test process building an AST at the same moment can
    trip it (python/cpython#106905, fixed in later releases). The source does not change, so
    a second parse gives the one answer."""
    text = path.read_text(encoding="utf-8")
    for attempt in range(5):
        try:
            return ast.parse(text, filename=str(path))
        except SystemError as exc:
            if "recursion depth mismatch" not in str(exc) or attempt == 4:
                raise
            time.sleep(0.05)
    raise AssertionError("unreachable")
